"""Whether warm-ups pay on this host: the runtime finds out by trying.

A warm-up before a frame (edge/runtime/prewarm.py) costs one more gate pass and model call of
CPU per frame; what it buys depends on the host (its caches, its idle states, how a sleep
wakes) and on the load (many sensors keep the core warm by themselves). So with
``RuntimeOptions.prewarm='auto'`` (the default) :class:`PrewarmDecision` alternates windows of
:data:`WINDOW_NS` with and without warm-ups, in the order of :data:`PATTERN` (balanced, so a
drift in the load favours neither), after :data:`SETTLE_NS` of the runtime's first frames
(the gate still learns its background, the cadence is not known yet), and again every
:data:`RETRY_NS`. The first :data:`GUARD_NS` of each window are not measured (the switch
itself: a grabber thread started or retired, the first warm-up's rest planned), so the trial
sees what each kind costs while it lasts. Over the windows of each kind it compares, from every
reading's total latency, the p50 of all readings and each sensor's tail, and the process CPU
time per reading (``time.process_time_ns``). Warm-ups stay on only when

- the core is not already busy: without warm-ups the process used under :data:`BUSY_SHARE`
  of one core (many sensors keep it warm by themselves), and warm-ups ran at all (frames far
  enough apart for the rest before one);
- they do not raise any sensor's tail (:func:`tail_raised`: of a sensor's largest 2 % of
  readings of both kinds together, more came with warm-ups than their share of the readings
  explains, one-sided binomial test at :data:`ALPHA` shared over the sensors; the p99 of a
  hundred or so readings is one of their largest two, so comparing two such numbers would
  turn warm-ups off about half the time where they change nothing);
- they lower the p50 by a larger share than the share of CPU per reading they add.

Else they are off until the next trial. :attr:`PrewarmDecision.state` says which and why
(``RuntimeStats.prewarm``). The clock and the CPU clock are injectable: tests drive a
decision with a fake clock and a cost model of their own.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from ..reading import Flags, ForceReading

#: The runtime's first frames, never judged (ns): the gate learns its background, the
#: cadence is not known yet.
SETTLE_NS = 1_000_000_000
#: One trial window (ns).
WINDOW_NS = 500_000_000
#: The start of each window not measured (ns): the switch between the kinds settles.
GUARD_NS = 100_000_000
#: Warm-ups on (True) or off in the trial's windows, in order: as many of each, balanced
#: (ABBA BAAB ABBA: a linear drift in the load favours neither).
PATTERN = (True, False, False, True, False, True, True, False, True, False, False, True)
#: How long a decision holds before the next trial (ns).
RETRY_NS = 60_000_000_000
#: Process CPU time, as a share of one core, over which the core counts as busy without
#: warm-ups: they are then never kept.
BUSY_SHARE = 0.5
#: Readings each kind of window needs before the trial judges anything.
MIN_READINGS = 20
#: Readings kept per window (a back-to-back source gives thousands; the percentiles do not
#: need them all).
MAX_KEPT = 10_000
#: The chance, over all sensors together, that the trial calls a sensor's tail raised by
#: warm-ups that change nothing (:func:`tail_raised`).
ALPHA = 0.05
#: The tail :func:`tail_raised` looks at: the readings at or over this percentile of both kinds
#: together. A raised p99 puts more readings with warm-ups there; the top 1 % of a trial's
#: readings are too few (three or so) for any count of them to tell.
TAIL_PERCENTILE = 98.0

_STALE = int(Flags.STALE)

Mode = Literal["auto", True, False]


@dataclass
class Arm:
    """The trial's windows of one kind (with or without warm-ups): each sensor's total
    latencies (ms), the process CPU time and wall time they took (ns), their readings and
    the warm-ups run."""

    totals: dict[str, list[float]] = field(default_factory=dict)
    cpu_ns: int = 0
    wall_ns: int = 0
    readings: int = 0
    warm_ups: int = 0

    @property
    def p50(self) -> float:
        """Total latency p50 over every reading (ms)."""
        values = [v for t in self.totals.values() for v in t]
        return float(np.percentile(values, 50)) if values else float("nan")

    @property
    def worst_p99(self) -> float:
        """The worst sensor's total latency p99 (ms)."""
        return max((float(np.percentile(t, 99)) for t in self.totals.values() if t), default=float("nan"))

    @property
    def cpu_per_reading_ns(self) -> float:
        return self.cpu_ns / self.readings if self.readings else float("nan")

    @property
    def cpu_share(self) -> float:
        """Process CPU time over wall time (1.0 = one core busy)."""
        return self.cpu_ns / self.wall_ns if self.wall_ns > 0 else 0.0


def tail_raised(off: list[float], on: list[float], alpha: float) -> bool:
    """Whether one sensor's latencies (ms) with warm-ups (``on``) have a heavier tail than
    without (``off``): of the readings at or over the :data:`TAIL_PERCENTILE` of both together,
    more are ``on`` ones than ``on``'s share of all readings explains, by a one-sided binomial
    test at ``alpha`` (under the same distribution each such reading is an ``on`` one with that
    share's chance, whatever the distribution)."""
    if not off or not on:
        return False
    both = np.concatenate([off, on])
    top = float(np.percentile(both, TAIL_PERCENTILE))
    a = int(np.count_nonzero(np.asarray(off) >= top))
    b = int(np.count_nonzero(np.asarray(on) >= top))
    m, share = a + b, len(on) / len(both)
    # the binomial tail by hand: scipy.stats would load (a few hundred ms) inside the reading loop
    chance = sum(math.comb(m, j) * share ** j * (1.0 - share) ** (m - j) for j in range(b, m + 1))
    return chance < alpha


def judge(off: Arm, on: Arm) -> tuple[bool, str]:
    """Whether warm-ups stay on, from the windows without (``off``) and with (``on``) them,
    and the state saying why (``"on (...)"`` or ``"off (...)"``)."""
    if off.readings < MIN_READINGS or on.readings < MIN_READINGS:
        return False, (f"off (too few readings to judge: {off.readings} without warm-ups, {on.readings} with; "
                       f"{MIN_READINGS} needed)")
    if off.cpu_share >= BUSY_SHARE:
        return False, f"off (core busy: {100 * off.cpu_share:.0f} % of one core without warm-ups)"
    if on.warm_ups == 0:
        return False, "off (no rest before a frame long enough for a warm-up)"
    p99s = f"worst sensor's p99 {on.worst_p99:.3f} ms with warm-ups, {off.worst_p99:.3f} ms without"
    names = sorted(set(off.totals) | set(on.totals))
    raised = [n for n in names if tail_raised(off.totals.get(n, []), on.totals.get(n, []), ALPHA / len(names))]
    if raised:
        return False, f"off (they raise the latency tail of {', '.join(raised)}: {p99s})"
    gain = 1.0 - on.p50 / off.p50 if off.p50 > 0 else 0.0
    base = off.cpu_per_reading_ns
    cost = on.cpu_per_reading_ns / base - 1.0 if base > 0 else (0.0 if on.cpu_per_reading_ns <= 0 else float("inf"))
    said = f"p50 {-100 * gain:+.0f} % for {100 * cost:+.0f} % CPU per reading"
    if not gain > cost:
        return False, f"off ({said})"
    return True, f"on ({said}; {p99s})"


class PrewarmDecision:
    """Whether the runtime warms up before frames now (see the module docstring).

    Parameters
    ----------
    mode : 'auto', True or False
        ``RuntimeOptions.prewarm``: decide on the host, always, never.
    clock : callable
        Monotonic ns (the runtime's clock).
    cpu : callable
        The process's CPU time in ns (default ``time.process_time_ns``).

    The runtime calls :meth:`active` at the start of each step (warm up in this step or
    not), :meth:`add` with the step's readings while :attr:`recording`, and :meth:`warmed`
    after each warm-up.
    """

    def __init__(self, mode: Mode, clock: Callable[[], int],
                 cpu: Callable[[], int] = time.process_time_ns) -> None:
        self.clock, self.cpu = clock, cpu
        self.auto = mode == "auto"
        #: 'trying', 'on (why)' or 'off (why)'
        self.state = ("trying" if self.auto else "on (RuntimeOptions.prewarm=True)" if mode
                      else "off (RuntimeOptions.prewarm=False)")
        self._on = mode is True
        #: whether the step's readings count for the trial (a window is open)
        self.recording = False
        self._next = -1  # when the current window (or settling, or the decision) ends (ns)
        self._i = -1  # the trial's window under way (-1: none)
        self._arms = {True: Arm(), False: Arm()}
        self._t0 = self._cpu0 = 0
        self._end = -1  # when the current window ends (ns)
        #: trials finished
        self.trials = 0

    @property
    def watching(self) -> bool:
        """Whether the runtime keeps what a warm-up needs (each sensor's cadence and last
        input): while warm-ups run, and while they may run soon (settling, a trial under way);
        not while a decision to leave them off holds (until the next trial) or they are never on."""
        return self._on or (self.auto and (self._i >= 0 or self.trials == 0))

    def active(self) -> bool:
        """Whether warm-ups run in the step that starts now (advances the trial's windows)."""
        if not self.auto:
            return self._on
        now = self.clock()
        if now >= self._next:
            self._turn(now)
        return self._on

    def add(self, readings: Iterable[ForceReading]) -> None:
        """Count the step's readings (stale ones are not measured) for the window under way."""
        if not self.recording:
            return
        arm = self._arms[self._on]
        for r in readings:
            if int(r.flags) & _STALE:
                continue
            arm.readings += 1
            t = arm.totals.setdefault(r.sensor, [])
            if len(t) < MAX_KEPT:
                t.append(r.latency.total_ms)

    def warmed(self) -> None:
        """A warm-up ran (in the window under way)."""
        if self.recording:
            self._arms[self._on].warm_ups += 1

    def _turn(self, now: int) -> None:
        if self._next < 0:  # the first step: let the runtime settle
            self._next = now + SETTLE_NS
            return
        if self._i >= 0 and not self.recording:  # the window's guard is over: measure the rest of it
            self.recording = True
            self._t0, self._cpu0, self._next = now, self.cpu(), self._end
            return
        if self.recording:  # close the window under way
            arm = self._arms[self._on]
            arm.cpu_ns += self.cpu() - self._cpu0
            arm.wall_ns += now - self._t0
        self._i += 1
        if self._i >= len(PATTERN):  # the trial is over: decide until the next one
            self._on, self.state = judge(self._arms[False], self._arms[True])
            self.recording, self._i, self._next = False, -1, now + RETRY_NS
            self.trials += 1
            return
        if self._i == 0:
            self._arms = {True: Arm(), False: Arm()}
            self.state = "trying"
        self._on = PATTERN[self._i]
        self.recording = False
        self._end = now + WINDOW_NS
        self._next = now + GUARD_NS
