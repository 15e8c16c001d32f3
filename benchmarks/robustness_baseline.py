"""The robustness catalogue run against an older commit's package, for a before/after table.

    python -m benchmarks.robustness_baseline 9ed225d [--examples 100]

The commit's edge/, export/ and firmware_bridge/ are extracted with ``git archive`` into a
temporary folder and imported as ``tactile_force`` instead of the installed package; the
catalogue (cases, oracles, classification) is this checkout's benchmarks/robustness.py. The
markdown table goes to stdout. Nothing in the repository is changed.
"""

from __future__ import annotations

import argparse
import io
import subprocess
import sys
import tarfile
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

_CHILD = """
import logging, sys
sys.path.insert(0, {repo!r})
from benchmarks import robustness as r
r.use_package_root({root!r})
import tactile_force.edge
assert tactile_force.edge.__file__.startswith({root!r}), tactile_force.edge.__file__
logging.getLogger("tactile_force").addHandler(logging.NullHandler())
tallies = r.run_catalogue({examples}, log=lambda s: print(s, file=sys.stderr, flush=True))
print(r.table(tallies))
"""


def baseline_table(commit: str, examples: int) -> str:
    """The catalogue's markdown table for ``commit`` (runs in a child Python process)."""
    archive = subprocess.run(["git", "-C", str(REPO), "archive", commit, "edge", "export", "firmware_bridge"],
                             capture_output=True, check=True).stdout
    with tempfile.TemporaryDirectory(prefix="tf_baseline_") as tmp:
        src = Path(tmp) / "src"
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(src, filter="data")
        pkg = Path(tmp) / "pkg" / "tactile_force"
        pkg.mkdir(parents=True)
        for name in ("edge", "export", "firmware_bridge"):
            (pkg / name).symlink_to(src / name, target_is_directory=True)
        code = _CHILD.format(repo=str(REPO), root=str(pkg.parent), examples=examples)
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=1800)
        if out.returncode != 0:
            raise RuntimeError(f"baseline run at {commit} failed: {out.stderr[-2000:]}")
        return out.stdout.strip()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.robustness_baseline", description=__doc__)
    ap.add_argument("commit", help="commit to measure, e.g. 9ed225d")
    ap.add_argument("--examples", type=int, default=100, help="generated cases per generated category")
    args = ap.parse_args(argv)
    print(baseline_table(args.commit, args.examples))
    return 0


if __name__ == "__main__":
    sys.exit(main())
