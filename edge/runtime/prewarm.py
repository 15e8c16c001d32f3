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

:class:`WarmUps` is what the runtime (``ForceRuntime``) calls: it takes each step's reads
(in the loop's thread, or from the grabber threads a rest is taken on), plans the rest before
a due frame with :class:`Prewarm`, runs or abandons the warm-up, hands one sensor's reads
back to the loop's thread while warm-ups do not run, and feeds the 'auto' trial of
:class:`~.prewarm_decision.PrewarmDecision`.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Mapping
from typing import TYPE_CHECKING, Protocol

from ..reading import ForceReading, StageLatency
from .depth_factory import depth_of
from .grabbers import Grabbers, Read, read_once
from .prewarm_decision import PrewarmDecision

if TYPE_CHECKING:
    from ..frames import TimedFrame
    from ..gate.contact_gate import GateResult
    from .gating import GateStep
    from .judging import Judge
    from .options import ForceModel, RuntimeOptions, RuntimeStats, Sensor

_log = logging.getLogger(__name__.rpartition(".")[0] + ".loop")  # the runtime's warnings, on its one logger

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


class WarmLane(Protocol):
    """What a warm-up reads of one sensor's lane in the runtime: its gate step and, when its
    last frame went to the model, that frame, its raw force and its gate result (else None)."""

    gating: GateStep
    last: tuple[TimedFrame, float, GateResult] | None


class WarmUps:
    """The runtime's reads and the warm-ups in the rests before them (see the module docstring).

    Parameters
    ----------
    sensors : list of Sensor
        The runtime's sensors (their names in a warning).
    model : ForceModel
        The runtime's model (its ``prewarm``, when it has one, is the warm-up's model call).
    judge : Judge
        The runtime's judge (a warm-up runs its estimate once more; the reading is dropped).
    lanes : mapping
        Sensor name -> its lane (:class:`WarmLane`).
    options : RuntimeOptions
        ``grabbers`` and ``prewarm``.
    clock : callable
        Monotonic ns, the runtime's clock (warm-ups run only on ``time.monotonic_ns``).
    stats : RuntimeStats
        The runtime's stats (``prewarm``, ``prewarms``, ``prewarm_abandoned``,
        ``prewarm_overran`` are kept here).
    """

    def __init__(self, sensors: list[Sensor], model: ForceModel, judge: Judge, lanes: Mapping[str, WarmLane],
                 options: RuntimeOptions, clock: Callable[[], int], stats: RuntimeStats) -> None:
        self.sensors, self.clock, self.stats = sensors, clock, stats
        self._judge, self._lanes = judge, lanes
        use = options.grabbers
        #: whether reads are taken from grabber threads (two or more sensors, unless told)
        self.use_grabbers = len(sensors) > 1 if use is None else bool(use)
        #: the grabber threads while they run
        self.grabbers: Grabbers | None = None
        # Getting ready shortly before the next frame is due at a slow cadence, where it pays
        # on this host (prewarm_decision.py): only with the real clock, which the rest is
        # taken on, and grabber threads, whose frame ends the rest (one sensor has a grabber
        # thread only while warm-ups run).
        mode = options.prewarm if options.prewarm == "auto" else bool(options.prewarm)
        blocked = ("the runtime's clock is injected; the rest is taken on time.monotonic_ns"
                   if clock is not time.monotonic_ns else
                   "RuntimeOptions.grabbers=False: nothing could end the rest when a frame arrives"
                   if use is not None and not use else "")
        #: whether warm-ups run now ('auto': tried on the host)
        self.decision = PrewarmDecision(False if blocked else mode, clock)
        if blocked and mode is not False:
            self.decision.state = f"off ({blocked})"
        #: when to warm up (None: warm-ups are off for this runtime)
        self.prewarm = Prewarm(clock) if mode is not False and not blocked else None
        self._lone = use is None and len(sensors) == 1  # a grabber thread only while warm-ups run
        stats.prewarm = self.decision.state
        #: whether each frame's arrival and the last input are kept for a warm-up (not while a
        #: decision to leave warm-ups off holds: then a reading runs the path of prewarm=False)
        self.watching = self.prewarm is not None and self.decision.watching
        self._model_prewarm: Callable[[int], None] | None = getattr(model, "prewarm", None)

    def read(self, live: list[Sensor]) -> list[tuple[Sensor, Read]]:
        """The step's reads of the ``live`` sensors: each read in the loop's thread, or those
        the grabber threads have; when warm-ups run in this step, after a rest until shortly
        before the next frame is due and the warm-up (given up when a frame arrives)."""
        warm = self.prewarm
        wait_ns = -1
        if warm is not None:
            if self.decision.active():  # warm-ups in this step (prewarm_decision.py)
                wait_ns = warm.wait_ns(s.name for s in live)
            elif self._lone and self.grabbers is not None:  # back to the loop's thread
                self._retire_grabber(self.grabbers)
            self.watching = self.decision.watching
            self.stats.prewarm = self.decision.state
        if self.use_grabbers or wait_ns >= 0:  # a rest is taken on the grabbers: a frame ends it
            grabbers = self.start()
            reads = grabbers.take(live, wait_ns / 1e9) if wait_ns >= 0 else grabbers.take(live)
            if not reads and warm is not None:  # rested until shortly before the next frame
                self._warm_up(warm, live, grabbers)
                reads = grabbers.take(live)
        else:
            reads = [(s, read_once(s.source, self.clock)) for s in live]
        return reads

    def seen(self, name: str, arrival_ns: int) -> None:
        """A frame of sensor ``name`` arrived at ``arrival_ns`` (ns; kept only while warm-ups
        may run: :attr:`watching`)."""
        warm = self.prewarm
        if warm is not None and self.watching:
            warm.seen(name, arrival_ns)
            self.stats.prewarm_overran = warm.overran

    def record(self, readings: list[ForceReading]) -> None:
        """The step's readings, for the 'auto' trial's window under way."""
        if self.decision.recording:
            self.decision.add(readings)

    def start(self) -> Grabbers:
        """The grabber threads, started now unless they run."""
        g = self.grabbers
        if g is not None and g.retiring and g.retired():  # warm-ups again after a retired grabber
            g.stop()
            self.grabbers = None
        if self.grabbers is None:
            self.grabbers = Grabbers(self.sensors, self.clock)
            self.use_grabbers = True
        return self.grabbers

    def _retire_grabber(self, g: Grabbers) -> None:
        """One sensor without warm-ups is read in the loop's thread again (the lowest-latency
        path), once the grabber has handed over the read it was making."""
        g.retire()
        if g.retired():
            g.stop()
            self.grabbers, self.use_grabbers = None, False

    def _warm_up(self, warm: Prewarm, live: list[Sensor], grabbers: Grabbers) -> None:
        """The warm-up before the next frame, timed and counted; given up as soon as a frame
        is there."""
        warm.timed(lambda: self._warm_parts(live, lambda: grabbers.ready(live)))
        self.decision.warmed()
        st = self.stats
        st.prewarms, st.prewarm_abandoned = warm.count, warm.abandoned

    def _warm_parts(self, live: list[Sensor], arrived: Callable[[], bool]) -> float:
        """Each live sensor's gate step once more on its last frame and, when that frame went
        to the model, its judge and depth stage (depth bundles), then one model call on the
        last input; results thrown away, no state changed. Given up before any of these parts
        once ``arrived()`` says a frame is there; returns the share of the parts it ran. A
        warm-up that fails turns warm-ups off (one warning): it is never worth a reading."""
        parts = len(live) + 1
        try:
            n = 0
            for k, s in enumerate(live):
                if arrived():
                    return k / parts
                lane = self._lanes[s.name]
                lane.gating.prewarm()
                if lane.last is not None:
                    n += 1
                    tf, raw, g = lane.last
                    self._judge.estimate(s.name, tf, raw, g, StageLatency())  # pure: the reading is dropped
                    if s.depth is not None:  # into the stage's buffers
                        depth_of(s.depth, lane.gating.frame, g)
            if n and self._model_prewarm is not None:
                if arrived():
                    return len(live) / parts
                self._model_prewarm(n)
        except Exception as exc:  # noqa: BLE001 - the frame that follows must still be served
            self.prewarm, self.watching = None, False
            self.decision = PrewarmDecision(False, self.clock)
            self.stats.prewarm = self.decision.state = f"off (a warm-up failed: {type(exc).__name__}: {exc})"
            _log.warning("ForceRuntime(%s): a warm-up before a frame failed (%s: %s); warm-ups are off for this "
                         "runtime", ", ".join(s.name for s in self.sensors), type(exc).__name__, exc)
        return 1.0
