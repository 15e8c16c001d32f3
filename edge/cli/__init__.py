"""``tactile-force``: the console script (``main``) and one module per verb (``configure(parser)``
and ``main(args) -> int``), imported only when its verb runs."""

from __future__ import annotations

from .main import COMMANDS, Interrupted, main

__all__ = ["COMMANDS", "Interrupted", "main"]
