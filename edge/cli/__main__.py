"""``python -m tactile_force.edge.cli``: the console script."""

import sys

from .main import main

sys.exit(main())
