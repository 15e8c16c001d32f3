"""The ``tactile-force`` process's first act: a Ctrl-C (or SIGTERM) that arrives while the
CLI is still starting (the interpreter importing this package, the chosen verb's module)
ends the process with 130 (143) and one line, never a traceback.

Imported first by ``tactile_force.edge`` (standard library only, so nothing runs before
it); it installs its handler only in a process started as the CLI (the ``tactile-force``
console script or ``python -m tactile_force.edge.cli``, read from ``sys.orig_argv``), so a
program that imports the package keeps its own signal handling. Once a verb runs,
:func:`tactile_force.edge.cli.main` replaces this handler with one that unwinds the verb
(removing a half-made output) and exits the same way.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from types import FrameType

#: the console script's file names (``-script.py`` / ``.exe``: the Windows launchers)
SCRIPT_NAMES = frozenset({"tactile-force", "tactile-force-script.py", "tactile-force.exe"})
#: the module ``python -m`` runs as the CLI
CLI_MODULE = "tactile_force.edge.cli"
#: interpreter options that take the next word as their value
_OPTION_WITH_VALUE = frozenset({"-X", "-W", "--check-hash-based-pycs"})


def started_as_cli(orig_argv: list[str] | None = None) -> bool:
    """Whether the interpreter's command line (``sys.orig_argv``) runs the CLI."""
    argv = list(getattr(sys, "orig_argv", []) if orig_argv is None else orig_argv)
    words = iter(argv[1:])
    for word in words:
        if word == "-m":
            return next(words, "") == CLI_MODULE
        if word.startswith("-m") and not word.startswith("--"):
            return word[2:] == CLI_MODULE
        if word == "-c" or (word.startswith("-c") and not word.startswith("--")):
            return False
        if word in _OPTION_WITH_VALUE:
            next(words, None)
            continue
        if word.startswith("-"):
            continue
        return os.path.basename(word) in SCRIPT_NAMES
    return False


def _exit_at_start(signum: int, frame: FrameType | None) -> None:
    """Nothing has been written yet: one line, then exit 128 + the signal's number at once."""
    try:
        os.write(2, f"tactile-force: interrupted by {signal.Signals(signum).name} while starting\n".encode())
    finally:
        os._exit(128 + signum)


def install() -> bool:
    """Install :func:`_exit_at_start` for SIGINT and SIGTERM when this process is the CLI
    (main thread only); True when installed."""
    if not started_as_cli() or threading.current_thread() is not threading.main_thread():
        return False
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, _exit_at_start)
    return True


INSTALLED = install()
