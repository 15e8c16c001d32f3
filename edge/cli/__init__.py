"""``tactile-force``: the console script (``main``) and one module per verb (``configure(parser)``
and ``main(args) -> int``), imported only when its verb runs."""

from __future__ import annotations

from ..interrupts import Interrupted
from .main import COMMANDS, main

__all__ = ["COMMANDS", "Interrupted", "main"]
