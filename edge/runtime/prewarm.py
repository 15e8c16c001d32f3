"""Getting ready for the next frame shortly before it is due.

A sensor at 60 fps leaves the core idle for most of each 16.7 ms frame period; after that
rest the next frame's gate and model calls run on cold caches, branch predictors and core
idle states, and cost about twice what they cost back to back (docs/benchmarks/cadence.md).
The runtime knows the cadence from the frames' arrival stamps: :class:`Prewarm` predicts when
each sensor's next frame is due and, when the core would otherwise rest long enough to go
cold, has the runtime wake shortly before it and run the per-frame work once on the last
frame (the exposure check and :meth:`ContactGate.prewarm` into the gate's scratch buffers,
the judge, the depth stage of depth bundles, the model's bound input once more; every result
thrown away, no state changed). The real frame then finds the code and data warm. The
warm-up is timed so that it ends :data:`MARGIN_NS` before the frame is due: its own cold
duration and how late the rest before it ends (a sleep on a virtual machine wakes 0.1 to
0.3 ms late) are measured every time; a frame that arrives early waits for it (counted in
:attr:`Prewarm.overran`). A warm-up that fails turns warm-ups off for the runtime (one
warning); it never costs a reading.

It pays only where the core rests: sources read back to back (files, replays) or frames
closer than :data:`MIN_GAP_NS` (many sensors phase-shifted keep the core busy) are never
prepared for. ``RuntimeOptions(prewarm=False)`` turns it off (its CPU cost is one extra gate
pass and model call per frame: docs/benchmarks/cadence.md).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

#: Frames closer than this keep the core warm by themselves: no warm-up (ns).
MIN_PERIOD_NS = 4_000_000
#: Frames further apart than this are not a cadence (a paused source): no warm-up (ns).
MAX_PERIOD_NS = 1_000_000_000
#: The least rest before the warm-up that makes one worth it (ns): frames of sensors at
#: 60 fps phase-shifted by under 4 ms (five or more) keep the core warm by themselves.
MIN_GAP_NS = 4_000_000
#: How long before the frame is due the warm-up aims to end (ns): 0.15 ms measured best of
#: 0.3 / 0.15 / 0.05 (docs/benchmarks/cadence.md); a shorter rest leaves the core warmer, a
#: frame that comes early waits for the rest of the warm-up.
MARGIN_NS = 150_000
#: The warm-up's duration assumed before the first one is timed (ns).
FIRST_WARM_NS = 700_000
#: Arrival gaps kept per sensor (the period is their median: a dropped frame does not move it).
HISTORY = 5
#: Warm-up durations and wake-up delays kept (the lead is the maximum of each plus
#: :data:`MARGIN_NS`).
WARM_HISTORY = 8


class _Cadence:
    """One sensor's arrival stamps: the last one, the last :data:`HISTORY` gaps (ns) and the
    next frame's predicted arrival (``due``, -1 while no steady cadence is known), made once
    per frame."""

    __slots__ = ("last", "gaps", "i", "n", "due")

    def __init__(self) -> None:
        self.last = -1
        self.gaps = [0] * HISTORY
        self.i = 0
        self.n = 0
        self.due = -1

    def add(self, arrival_ns: int) -> None:
        if self.last >= 0 and arrival_ns > self.last:
            self.gaps[self.i] = arrival_ns - self.last
            self.i = (self.i + 1) % HISTORY
            self.n = min(self.n + 1, HISTORY)
        self.last = arrival_ns
        period = sorted(self.gaps[:self.n])[self.n // 2] if self.n >= 3 else 0
        self.due = arrival_ns + period if MIN_PERIOD_NS <= period <= MAX_PERIOD_NS else -1


class Prewarm:
    """When to warm up before the next frame (see the module docstring).

    Parameters
    ----------
    clock : callable
        Monotonic ns, the clock the frames' arrival stamps use.
    """

    def __init__(self, clock: Callable[[], int]) -> None:
        self.clock = clock
        self._cadence: dict[str, _Cadence] = {}
        self._warm = [FIRST_WARM_NS] * WARM_HISTORY
        self._late = [0] * WARM_HISTORY  # how late each rest ended (ns)
        self._wi = 0
        self._wake = -1  # when the rest planned by wait_ns() should end (ns)
        self._end = -1  # when the last warm-up ended (ns)
        #: warm-ups run (each a gate pass per sensor and, after a contact, one model call)
        self.count = 0
        #: frames that arrived while a warm-up still ran (they waited for it)
        self.overran = 0

    def seen(self, name: str, arrival_ns: int) -> None:
        """A frame of sensor ``name`` arrived at ``arrival_ns`` (ns)."""
        if arrival_ns < self._end:
            self.overran += 1
            self._end = -1
        c = self._cadence.get(name)
        if c is None:
            c = self._cadence[name] = _Cadence()
        c.add(arrival_ns)

    @property
    def lead_ns(self) -> int:
        """How long before the frame is due the rest before the warm-up is planned to end
        (ns): the warm-up's longest recent duration, the longest recent delay of a wake-up
        and :data:`MARGIN_NS`."""
        return max(self._warm) + max(self._late) + MARGIN_NS

    def wait_ns(self, names: Iterable[str]) -> int:
        """How long to rest before warming up for the next frame of any of ``names`` (ns), or
        -1: no warm-up now (no steady cadence, or too little rest before the frame)."""
        due = -1
        cadence = self._cadence
        for name in names:
            c = cadence.get(name)
            if c is None or c.due < 0:
                return -1
            due = c.due if due < 0 else min(due, c.due)
        if due < 0:
            return -1
        now = self.clock()
        wait = due - self.lead_ns - now
        if wait < MIN_GAP_NS:
            return -1
        self._wake = now + wait
        return wait

    def timed(self, warm_up: Callable[[], None]) -> None:
        """Run ``warm_up`` (after the rest :meth:`wait_ns` planned) and keep its duration and
        how late the rest ended for the next lead."""
        t0 = self.clock()
        wi = self._wi
        self._late[wi] = max(0, t0 - self._wake) if self._wake >= 0 else 0
        self._wake = -1
        warm_up()
        self._end = self.clock()
        self._warm[wi] = self._end - t0
        self._wi = (self._wi + 1) % WARM_HISTORY
        self.count += 1
