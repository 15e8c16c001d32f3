"""Print the core dependencies and the runtime extras' (``fast``: numba, ``paper``: scipy) pinned at their
declared minimums (``name>=X`` -> ``name==X``).

A dependency with a ``python_version < 'X.Y'`` marker is printed only where it applies.
"""

import pathlib
import re
import sys
import tomllib

project = tomllib.loads(pathlib.Path(__file__).resolve().parents[1].joinpath("pyproject.toml").read_text())["project"]
RUNTIME_EXTRAS = ("fast", "paper")  # the robot side's optional paths: their minimums are tested too
for dep in project["dependencies"] + [d for e in RUNTIME_EXTRAS for d in project["optional-dependencies"][e]]:
    spec, _, marker = dep.partition(";")
    marker = marker.strip()
    if marker:
        m = re.fullmatch(r"python_version\s*<\s*['\"](\d+)\.(\d+)['\"]", marker)
        if not m:
            raise SystemExit(f"pyproject dependency {dep!r}: .ci/min_versions.py understands only python_version < 'X.Y'")
        if sys.version_info[:2] >= (int(m.group(1)), int(m.group(2))):
            continue
    m = re.fullmatch(r"\s*([A-Za-z0-9_.-]+)\s*>=\s*([0-9][0-9A-Za-z.]*)\s*", spec)
    if not m:
        raise SystemExit(f"pyproject dependency {dep!r}: declare a minimum as NAME>=VERSION")
    print(f"{m.group(1)}=={m.group(2)}")
