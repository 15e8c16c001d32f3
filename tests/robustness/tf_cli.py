"""``tactile-force ARGS`` in a subprocess (for tests that send it signals or guard against a
hang). With TF_PACKAGE_ROOT set, the package is imported from there (a check of an older
commit's package)."""

import os
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

if os.environ.get("TF_PACKAGE_ROOT"):
    from benchmarks.robustness import use_package_root

    use_package_root(os.environ["TF_PACKAGE_ROOT"])

from tactile_force.edge.cli import main  # noqa: E402

sys.exit(main(sys.argv[1:]))
