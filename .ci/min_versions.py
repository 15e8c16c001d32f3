"""Print the core dependencies pinned at their declared minimums (``name>=X`` -> ``name==X``)."""

import pathlib
import re
import tomllib

project = tomllib.loads(pathlib.Path(__file__).resolve().parents[1].joinpath("pyproject.toml").read_text())["project"]
for dep in project["dependencies"]:
    m = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)\s*>=\s*([0-9][0-9A-Za-z.]*)\s*", dep)
    if not m:
        raise SystemExit(f"pyproject dependency {dep!r}: declare a minimum as NAME>=VERSION")
    print(f"{m.group(1)}=={m.group(2)}")
