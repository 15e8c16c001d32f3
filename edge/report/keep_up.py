"""Whether the host keeps up with its sensors: the share of late and stale readings, as a run goes.

A reading sink for ``tactile-force run``: every :data:`WINDOW_S` seconds where any reading was late
(older than the deadline when it came out) or stale (superseded by a newer frame before it was
processed) one line gives their shares in that window; once, when the two together stay above
:data:`WARN_SHARE` for :data:`WARN_WINDOWS` windows in a row, a warning says the host is not keeping
up and what to try; at the end :meth:`KeepUpWatch.summary` gives the shares over the whole run.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import TextIO

from ..reading import Flags, ForceReading

#: seconds per window of the running report
WINDOW_S = 10.0
#: late + stale share above which a window counts as not keeping up (docs/runtime.md)
WARN_SHARE = 0.05
#: windows in a row above :data:`WARN_SHARE` before the one warning
WARN_WINDOWS = 3


class KeepUpWatch:
    """Counts late and stale readings per window and over the run; writes to ``stream`` (stderr)."""

    def __init__(self, stream: TextIO | None = None, clock: Callable[[], float] = time.monotonic,
                 window_s: float = WINDOW_S) -> None:
        self.stream = stream or sys.stderr
        self._clock = clock
        self._window_s = float(window_s)
        self._start: float | None = None
        self._n = self._late = self._stale = 0  # this window
        self.total = self.total_late = self.total_stale = 0
        self._above = 0
        self.warned = False

    def write(self, r: ForceReading) -> None:
        now = self._clock()
        if self._start is None:
            self._start = now
        elif now - self._start >= self._window_s:
            self._close_window()
            self._start = now
        late, stale = Flags.LATE in r.flags, Flags.STALE in r.flags
        self._n += 1
        self._late += late
        self._stale += stale
        self.total += 1
        self.total_late += late
        self.total_stale += stale

    def _close_window(self) -> None:
        n = self._n
        if n and (self._late or self._stale):
            self.stream.write(f"\nlast {self._window_s:g} s: late {100 * self._late / n:.0f} %, stale "
                              f"{100 * self._stale / n:.0f} % of {n} readings\n")
        share = (self._late + self._stale) / n if n else 0.0
        self._above = self._above + 1 if share > WARN_SHARE else 0
        if self._above >= WARN_WINDOWS and not self.warned:
            self.warned = True
            self.stream.write(f"\nwarning: this host is not keeping up: over {100 * WARN_SHARE:g} % of the readings "
                              f"late or stale for {WARN_WINDOWS * self._window_s:g} s. Fewer sensors, a lower --fps, "
                              "or a smaller bundle (tactile-force compress); 'tactile-force bench' measures "
                              "what this host holds\n")
        self.stream.flush()
        self._n = self._late = self._stale = 0

    def summary(self) -> str:
        """The run's late and stale shares, one line ('' before any reading)."""
        if not self.total:
            return ""
        return (f"late {100 * self.total_late / self.total:.1f} %, stale {100 * self.total_stale / self.total:.1f} % "
                f"of {self.total} readings" + (" (the host did not keep up: see the warning above)" if self.warned
                                                else ""))

    def close(self) -> None:
        pass
