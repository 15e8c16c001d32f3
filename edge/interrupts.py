"""SIGINT and SIGTERM while a ``tactile-force`` verb runs: raised, remembered, never lost.

While :class:`CliSignals` is entered (the CLI's :func:`~tactile_force.edge.cli.main`, main
thread), both signals raise :class:`Interrupted` (a ``KeyboardInterrupt``) so the verb unwinds
through its clean-up. A library may swallow that exception (OpenCV's loader, for one, wraps
imports in a bare ``except``), so the signal is also remembered, and :func:`raise_pending`
raises it again at the checkpoints that matter: before a verb's long work starts, at every item
of a progress bar, and before an output is published. A signal that arrived is never followed
by a published result or a run that goes on as if nothing happened.

Outside the CLI (a program importing the package) nothing is installed and
:func:`raise_pending` does nothing. Standard library only.
"""

from __future__ import annotations

import signal
import threading
from types import FrameType

_active: CliSignals | None = None


class Interrupted(KeyboardInterrupt):
    """SIGINT or SIGTERM arrived while a command ran; ``signum`` says which."""

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class CliSignals:
    """SIGINT and SIGTERM raise :class:`Interrupted` while entered (main thread only; elsewhere
    nothing changes); ``received`` remembers the first, so a signal whose exception was
    swallowed is raised again by :func:`raise_pending` and never ends in exit 0."""

    def __init__(self) -> None:
        self.received: int | None = None
        self._old: dict[int, object] = {}
        self._outer: CliSignals | None = None

    def __enter__(self) -> CliSignals:
        global _active
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._old[sig] = signal.signal(sig, self._handle)
            self._outer, _active = _active, self
        return self

    def __exit__(self, *exc: object) -> None:
        global _active
        for sig, old in self._old.items():
            signal.signal(sig, old)  # type: ignore[arg-type]
        if self._old:
            _active = self._outer
        self._old.clear()

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.received is None:
            self.received = signum
        raise Interrupted(signum)

    def code(self, exc: BaseException | None = None) -> int:
        """128 + the signal's number (130 SIGINT, 143 SIGTERM)."""
        signum = exc.signum if isinstance(exc, Interrupted) else (self.received or signal.SIGINT)
        return 128 + int(signum)


def pending() -> int | None:
    """The signal the running CLI verb received (its number), or None (none, or not the CLI)."""
    return None if _active is None else _active.received


def raise_pending() -> None:
    """Raise :class:`Interrupted` again when the running CLI verb received a signal: its first
    exception was swallowed by code in between (main thread only; a no-op outside the CLI)."""
    signum = pending()
    if signum is not None and threading.current_thread() is threading.main_thread():
        raise Interrupted(signum)
