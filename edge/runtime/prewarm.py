"""Getting ready for the next frame shortly before it is due.

A sensor at 60 fps leaves the core idle for most of each 16.7 ms frame period; after that
rest the next frame's gate and model calls run on cold caches, branch predictors and core
idle states, and on some hosts cost about twice what they cost back to back
(docs/benchmarks/cadence.md). The runtime knows the cadence from the frames' arrival stamps:
:class:`Prewarm` predicts when each sensor's next frame is due and, when the core would
otherwise rest long enough to go cold, has the runtime wake shortly before it and run the
per-frame work once on the last frame (the exposure check and :meth:`ContactGate.prewarm`
into the gate's scratch buffers, the judge, the depth stage of depth bundles, the model's
bound input once more; every result thrown away, no state changed). The real frame then
finds the code and data warm.

Nothing here is tuned to one host: the warm-up is planned to end before the frame is due by
its own measured cold duration and how late the rest before it ended (a sleep on a virtual
machine wakes 0.1 to 0.3 ms late), each the largest of the last :data:`WARM_HISTORY`, and the
margin: how early frames came against their prediction, the median of the last
:data:`WARM_HISTORY` frames (a core left to rest even a fraction of a millisecond after the
warm-up goes cold again, and a frame that comes early waits at most for the warm-up's part
under way, so the typical earliness, not the worst). A planned rest never exceeds the
measured period. The runtime rests in a way a frame ends (its grabber threads:
``Grabbers.take`` with a timeout) and looks between the warm-up's parts (each sensor's gate
pass, the model call) whether a frame arrived: then the warm-up is abandoned
(:attr:`Prewarm.abandoned`) and the frame served at once, so a frame waits at most for the
one part under way. A warm-up that fails turns warm-ups off for the runtime (one warning);
it never costs a reading.

It pays only where the core rests: sources read back to back (files, replays) or frames
closer than :data:`MIN_GAP_NS` (many sensors phase-shifted keep the core busy) are never
prepared for. Whether it pays at all on this host the runtime measures
(:mod:`.prewarm_decision`, ``RuntimeOptions.prewarm='auto'``); its CPU cost is one extra gate
pass and model call per frame.
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
#: The warm-up's duration assumed before the first one is timed (ns).
FIRST_WARM_NS = 700_000
#: Arrival gaps kept per sensor (the period is their median: a dropped frame does not move it).
HISTORY = 5
#: Warm-up durations, wake-up delays and early arrivals kept (the lead is the sum of the
#: largest duration, the largest delay and the median earliness).
WARM_HISTORY = 8


class _Cadence:
    """One sensor's arrival stamps: the last one, the last :data:`HISTORY` gaps (ns), the
    period (their median, 0 while no steady cadence is known) and the next frame's predicted
    arrival (``due``, -1 while none), made once per frame."""

    __slots__ = ("last", "gaps", "i", "n", "due", "period")

    def __init__(self) -> None:
        self.last = -1
        self.gaps = [0] * HISTORY
        self.i = 0
        self.n = 0
        self.due = -1
        self.period = 0

    def add(self, arrival_ns: int) -> int:
        """Take the next arrival stamp (ns); return how much earlier than predicted it came
        (ns; 0 when it was not early or nothing was predicted; at most the period)."""
        early = self.due - arrival_ns if self.due > arrival_ns else 0
        if self.last >= 0 and arrival_ns > self.last:
            self.gaps[self.i] = arrival_ns - self.last
            self.i = (self.i + 1) % HISTORY
            self.n = min(self.n + 1, HISTORY)
        self.last = arrival_ns
        period = sorted(self.gaps[:self.n])[self.n // 2] if self.n >= 3 else 0
        steady = MIN_PERIOD_NS <= period <= MAX_PERIOD_NS
        self.period = period if steady else 0
        self.due = arrival_ns + period if steady else -1
        return min(early, self.period)


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
        self._early = [0] * WARM_HISTORY  # how early frames came against their prediction (ns)
        self._wi = 0
        self._ei = 0
        self._wake = -1  # when the rest planned by wait_ns() should end (ns)
        self._end = -1  # when the last warm-up ended (ns)
        #: warm-ups run to their end (each a gate pass per sensor and, after a contact, one
        #: model call)
        self.count = 0
        #: warm-ups abandoned because a frame arrived (the frame was served at once)
        self.abandoned = 0
        #: frames that arrived while a warm-up still ran
        self.overran = 0

    def seen(self, name: str, arrival_ns: int) -> None:
        """A frame of sensor ``name`` arrived at ``arrival_ns`` (ns)."""
        if arrival_ns < self._end:
            self.overran += 1
            self._end = -1
        c = self._cadence.get(name)
        if c is None:
            c = self._cadence[name] = _Cadence()
        self._early[self._ei] = c.add(arrival_ns)
        self._ei = (self._ei + 1) % WARM_HISTORY

    @property
    def margin_ns(self) -> int:
        """How much earlier than predicted frames came lately, the median of the last
        :data:`WARM_HISTORY` (ns): the warm-up aims to end this long before the frame is due."""
        return sorted(self._early)[WARM_HISTORY // 2]

    @property
    def lead_ns(self) -> int:
        """How long before the frame is due the rest before the warm-up is planned to end
        (ns): the warm-up's longest recent duration, the longest recent delay of a wake-up
        and :attr:`margin_ns`."""
        return max(self._warm) + max(self._late) + self.margin_ns

    def wait_ns(self, names: Iterable[str]) -> int:
        """How long to rest before warming up for the next frame of any of ``names`` (ns), or
        -1: no warm-up now (no steady cadence, or too little rest before the frame). Never
        more than the shortest of their measured periods less the lead."""
        due = -1
        period = MAX_PERIOD_NS
        cadence = self._cadence
        for name in names:
            c = cadence.get(name)
            if c is None or c.due < 0:
                return -1
            due = c.due if due < 0 else min(due, c.due)
            period = min(period, c.period)
        if due < 0:
            return -1
        now = self.clock()
        lead = self.lead_ns
        wait = min(due - lead - now, period - lead)
        if wait < MIN_GAP_NS:
            return -1
        self._wake = now + wait
        return wait

    def timed(self, warm_up: Callable[[], float]) -> bool:
        """Run ``warm_up`` (after the rest :meth:`wait_ns` planned; it returns the share of its
        parts it ran: under 1 when it was abandoned for a frame that arrived) and keep, for
        the next lead, how late the rest ended and its duration (of an abandoned one, the
        time it took over the share it ran: what the whole would have taken). True when it
        ran to its end."""
        t0 = self.clock()
        wi = self._wi
        self._late[wi] = max(0, t0 - self._wake) if self._wake >= 0 else 0
        self._wake = -1
        share = warm_up()
        self._end = self.clock()
        took = self._end - t0
        done = share >= 1.0
        if done:
            self._warm[wi] = took
            self.count += 1
        else:
            if share > 0:
                self._warm[wi] = min(int(took / share), MAX_PERIOD_NS)
            self.abandoned += 1
        self._wi = (self._wi + 1) % WARM_HISTORY
        return done
