"""Getting ready before a frame is due (edge/runtime/prewarm.py): when the runtime plans a
warm-up (a fake clock drives the plan), that a warm-up changes nothing a user sees (the
gate's decisions, the model's answers and every reading stay what they are without it, one,
two and eight sensors), and that a wait is bounded by what it is for (a stamp of another
clock is refused, a frame that arrives during a rest or a warm-up is served at once: bursty,
jittery and early fake cameras). Real ONNX Runtime sessions (the shipped default bundle),
real gates, real DIGIT frames; the real-time tests pace in-memory frames (fake cameras, the
hardware boundary) and assert counts and flags, no timing."""

from __future__ import annotations

import threading
import time

import cv2
import numpy as np
import pytest
from tactile_force.edge import TimedFrame
from tactile_force.edge.errors import ArgumentTypeError, SourceError
from tactile_force.edge.frames import FrameSource
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
from tactile_force.edge.runtime.grabbers import Grabbers
from tactile_force.edge.runtime.prewarm import (
    FIRST_WARM_NS,
    MIN_GAP_NS,
    Prewarm,
)
from tactile_force.edge.scene import default_bundle_path
from tactile_force.edge.sources import load_background

from tests.conftest import FakeClock, ListSource, shared_data

PERIOD = 16_666_667  # ns, 60 fps


# -- the plan ---------------------------------------------------------------------------------
def _seen(p: Prewarm, name: str, start: int, n: int, period: int = PERIOD) -> int:
    for i in range(n):
        p.seen(name, start + i * period)
    return start + (n - 1) * period


def test_no_warm_up_before_a_steady_cadence_is_known():
    clock = FakeClock(0)
    p = Prewarm(clock)
    assert p.wait_ns(["a"]) == -1  # never seen
    last = _seen(p, "a", clock.t, 3)  # two gaps: not yet a cadence
    clock.t = last + 1_000_000
    assert p.wait_ns(["a"]) == -1
    p.seen("a", last + PERIOD)
    clock.t = last + PERIOD + 1_000_000
    assert p.margin_ns == 0  # every frame came when predicted
    assert p.wait_ns(["a"]) == PERIOD - 1_000_000 - FIRST_WARM_NS


@pytest.mark.parametrize("period", [2_000_000, 3_000_000_000])
def test_no_warm_up_for_frames_back_to_back_or_a_paused_source(period):
    clock = FakeClock(0)
    p = Prewarm(clock)
    clock.t = _seen(p, "a", clock.t, 6, period)
    assert p.wait_ns(["a"]) == -1


def test_no_warm_up_when_the_rest_before_it_is_short():
    clock = FakeClock(0)
    p = Prewarm(clock)
    last = _seen(p, "a", clock.t, 6)
    due = last + PERIOD
    clock.t = due - p.lead_ns - MIN_GAP_NS + 1  # the core would rest under MIN_GAP_NS
    assert p.wait_ns(["a"]) == -1
    clock.t -= 2
    assert p.wait_ns(["a"]) == MIN_GAP_NS + 1


def test_the_next_frame_of_any_sensor_sets_the_plan_and_a_dropped_frame_does_not_move_it():
    clock = FakeClock(0)
    p = Prewarm(clock)
    start = clock.t
    _seen(p, "a", start, 5)
    last_b = _seen(p, "b", start + 5_000_000, 3)
    p.seen("b", last_b + 2 * PERIOD)  # b dropped a frame: its period stays the median gap
    clock.t = start + 4 * PERIOD + 100_000
    wait = p.wait_ns(["a", "b"])
    assert wait == start + 5 * PERIOD - p.lead_ns - clock.t  # a's frame is due first
    assert p.wait_ns(["a", "b", "c"]) == -1  # a sensor without a cadence yet: no plan


def test_the_lead_follows_the_measured_warm_up_and_wake_up():
    clock = FakeClock(0)
    p = Prewarm(clock)
    last = _seen(p, "a", clock.t, 5)
    clock.t = last + 1_000_000
    wait = p.wait_ns(["a"])
    clock.t += wait + 400_000  # the rest ended 0.4 ms late
    assert p.timed(lambda: clock.sleep(0.002) or 1.0)  # the warm-up took 2 ms
    assert p.count == 1
    assert p.lead_ns == 2_000_000 + 400_000
    p.seen("a", last + PERIOD - 500_000)  # the frame came 0.5 ms early, while the warm-up still ran
    assert p.overran == 1
    assert p.margin_ns == 0  # one early frame in eight: not the typical one
    for _ in range(4):  # now frames come 0.5 ms before their prediction more often than not
        p.seen("a", p._cadence["a"].due - 500_000)
    assert p.margin_ns == 500_000
    assert p.lead_ns == 2_000_000 + 400_000 + 500_000
    assert p.overran == 1


def test_an_abandoned_warm_up_is_counted_and_what_the_whole_takes_is_kept():
    clock = FakeClock(0)
    p = Prewarm(clock)
    _seen(p, "a", clock.t, 5)
    assert p.timed(lambda: clock.sleep(0.002) or 1.0)
    assert not p.timed(lambda: clock.sleep(0.001) or 0.25)  # a frame came after a quarter of its parts
    assert (p.count, p.abandoned) == (1, 1)
    assert max(p._warm) == 4_000_000  # what the whole would have taken
    assert not p.timed(lambda: 0.0)  # a frame came before it began: nothing learnt about its length
    assert max(p._warm) == 4_000_000


@pytest.mark.parametrize("ahead_s", [0.3, 1.8e9])  # a camera clock 0.3 s ahead; the wall clock (57 years)
def test_a_planned_rest_never_exceeds_the_measured_period(ahead_s):
    clock = FakeClock(0)
    p = Prewarm(clock)
    _seen(p, "a", clock.t + int(ahead_s * 1e9), 6)  # stamps far ahead of the runtime's clock
    wait = p.wait_ns(["a"])
    assert 0 < wait <= PERIOD - p.lead_ns


# -- nothing changes ------------------------------------------------------------------------
@pytest.fixture(scope="module")
def frames() -> tuple[np.ndarray, list[np.ndarray]]:
    """The no-contact background and a sequence that exercises every state of the gate: no
    contact, presses, a brightness step, a shifted image (the gel moved), pixel noise, and
    the background again."""
    (free,) = load_background(shared_data("digit_backgrounds", "aurova_background_b.png"))
    images = shared_data("aurova_digit_grasp", "images")
    touch = [cv2.imread(str(p)) for p in sorted(images.glob("*.png"))]
    rng = np.random.default_rng(0)
    bright = np.clip(free.astype(np.int16) + 40, 0, 255).astype(np.uint8)
    shifted = np.roll(free, 12, axis=1)
    noisy = np.clip(free + rng.normal(0, 25, free.shape), 0, 255).astype(np.uint8)
    seq = [free, free, *touch[:5], free, bright, bright, *touch[5:], shifted, shifted, noisy, free, free, *touch[:3]]
    return free, seq


def _decision(g) -> tuple:
    return (g.contact, g.area_px, g.saturation_seen, g.mismatch, g.invalid, round(g.deformation, 9), g.gain,
            g.offset, g.thumb.tobytes(), g.mask.tobytes())


def test_gate_prewarm_changes_no_decision(frames):
    free, seq = frames
    plain, warmed = ContactGate(), ContactGate()
    plain.capture_background([free])
    warmed.capture_background([free])
    warmed.prewarm()  # before any live frame: nothing to warm on
    for i, f in enumerate(seq):
        a = _decision(plain.update(f))
        b = _decision(warmed.update(f))
        assert a == b, f"frame {i}: the gate decided otherwise after a warm-up"
        warmed.prewarm()
        warmed.prewarm()
        assert warmed.state == plain.state
    assert warmed.relearned == plain.relearned


def test_gate_prewarm_before_a_background_does_nothing(frames):
    free, _ = frames
    g = ContactGate()
    g.prewarm()
    g.update(free)
    g.prewarm()  # still learning: nothing to compare with
    assert not g.background_ready


@pytest.fixture(scope="module")
def model():
    m = OnnxForceModel(default_bundle_path())
    yield m
    m.close()


def test_model_prewarm_changes_no_answer(frames, model):
    _, seq = frames
    a, b = np.stack(seq[2:4]), np.stack(seq[5:6])
    alone = model.predict(b)
    first = model.predict(a)
    model.prewarm(2)
    model.prewarm(1)
    model.prewarm(16)  # a batch not bound yet: nothing to run
    np.testing.assert_array_equal(model.predict(b), alone)
    np.testing.assert_array_equal(model.predict(a), first)


def test_model_prewarm_after_close_does_nothing():
    m = OnnxForceModel(default_bundle_path())
    m.close()
    m.prewarm()


def test_prewarm_option_is_checked():
    with pytest.raises(ArgumentTypeError, match="RuntimeOptions.prewarm"):
        RuntimeOptions(prewarm="yes")  # type: ignore[arg-type]


class PacedList(ListSource):
    """Frames in memory arriving at ``fps`` in real time (read() sleeps until each is due),
    stamped when due, like a camera."""

    def __init__(self, frames, fps: float, offset_s: float = 0.0) -> None:
        super().__init__(frames)
        self.period = int(1e9 / fps)
        self.t0 = time.monotonic_ns() + int(offset_s * 1e9) + 50_000_000

    def read(self):
        i = self.stats.frames
        if i >= len(self.frames):
            return None
        due = self.t0 + i * self.period
        now = time.monotonic_ns()
        if due > now:
            time.sleep((due - now) / 1e9)
        self.stats.frames += 1
        return TimedFrame(self.frames[i], due, i, arrival_ns=max(due, 0))


@pytest.fixture(scope="module")
def depth_model():
    """The shipped D bundle (its depth stage is warmed up too)."""
    from tactile_force.edge.scene import shipped_bundles

    path = shipped_bundles().get("d")
    if path is None:
        pytest.skip("the shipped D bundle is not in edge/models")
    m = OnnxForceModel(path)
    yield m
    m.close()


def _run(frames, free, model, n_sensors: int, prewarm: bool, paced: bool):
    sensors = []
    # a hand's frames arrive together, at 20 fps: the core rests between them, even on a busy host
    shift, fps = (0.004, 50) if n_sensors <= 2 else (0.0, 20)
    for k in range(n_sensors):
        g = ContactGate()
        g.capture_background([free])
        src = PacedList(frames, fps, offset_s=k * shift) if paced else ListSource(frames)
        sensors.append(Sensor(f"s{k}", src, g))
    rt = ForceRuntime(sensors, model, RuntimeOptions(deadline_ms=1e6, prewarm=prewarm), owns_model=False)
    try:
        out = []
        while not rt.finished:
            out += [(r.sensor, r.frame_index, r.force_n, int(r.flags), r.contact_area_px, r.detail)
                    for r in rt.step()]
        return sorted(out, key=lambda r: (r[0], r[1])), rt.stats
    finally:
        rt.close()


@pytest.mark.parametrize("n_sensors", [1, 2, 8])
def test_readings_with_warm_ups_equal_readings_without(frames, model, n_sensors):
    """One sensor (read in a grabber thread while warm-ups run), two and
    eight (grabber threads) at 50 / 20 fps: the runtime warms up before frames (counted) and
    every reading is the one made without."""
    free, seq = frames
    seq = seq[:20]
    want, _ = _run(seq, free, model, n_sensors, prewarm=False, paced=False)
    got, stats = _run(seq, free, model, n_sensors, prewarm=True, paced=True)
    assert stats.prewarms > 0
    np.testing.assert_equal(got, want)


def test_depth_readings_with_warm_ups_equal_readings_without(frames, depth_model):
    free, seq = frames
    seq = seq[:14]
    want, _ = _run(seq, free, depth_model, 1, prewarm=False, paced=False)
    got, stats = _run(seq, free, depth_model, 1, prewarm=True, paced=True)
    assert stats.prewarms > 0
    np.testing.assert_equal(got, want)


def test_no_warm_up_with_an_injected_clock_or_back_to_back(frames, model):
    free, seq = frames
    g = ContactGate()
    g.capture_background([free])
    rt = ForceRuntime([Sensor("s", ListSource(seq), g)], model, RuntimeOptions(deadline_ms=1e6), owns_model=False,
                      clock=FakeClock(PERIOD))  # readings 16.7 ms apart, but on a clock the runtime cannot sleep on
    rt.run()
    rt.close()
    assert rt.stats.prewarms == 0
    _, stats = _run(seq, free, model, 1, prewarm=True, paced=False)  # back to back: the core never rests
    assert stats.prewarms == 0


def test_grabbers_take_returns_nothing_when_the_wait_ends_first():
    release = threading.Event()

    class Blocked:
        name = "blocked"

        def read(self):
            release.wait(20.0)
            return None

        def close(self):
            pass

    class S:
        def __init__(self) -> None:
            self.name, self.source = "a", Blocked()

    s = S()
    grabbers = Grabbers([s], time.monotonic_ns)
    try:
        assert grabbers.take([s], timeout_s=0.01) == []
        release.set()
        got = grabbers.take([s], timeout_s=20.0)
        assert [x[0] for x in got] == [s] and got[0][1].tf is None
    finally:
        grabbers.stop()


def test_a_failing_warm_up_turns_warm_ups_off_and_costs_no_reading(frames, model, monkeypatch, caplog):
    free, seq = frames
    seq = seq[:12]
    want, _ = _run(seq, free, model, 1, prewarm=False, paced=False)

    def broken(self) -> None:
        raise RuntimeError("warm-up broke")

    monkeypatch.setattr(ContactGate, "prewarm", broken)
    got, stats = _run(seq, free, model, 1, prewarm=True, paced=True)
    np.testing.assert_equal(got, want)
    assert stats.prewarms == 1  # the one that failed; then off
    assert sum("warm-ups are off" in r.getMessage() for r in caplog.records) == 1


# -- waits bounded by what they are for -------------------------------------------------------
class ScriptedCamera(FrameSource):
    """A fake camera (the hardware boundary): frame i arrives ``arrive_s[i]`` seconds after the
    first read (read() sleeps until then) and is stamped with ``time.monotonic_ns()`` when in
    hand, plus ``ahead_ns`` (a camera clock that runs ahead), or with ``stamp()`` when given."""

    name = "scripted"

    def __init__(self, frames, arrive_s, ahead_ns: int = 0, stamp=None) -> None:
        super().__init__()
        self.frames, self.arrive_s, self.ahead_ns, self.stamp = list(frames), list(arrive_s), ahead_ns, stamp
        self.t0: int | None = None

    def read(self):
        i = self.stats.frames
        if i >= len(self.arrive_s):
            return None
        if self.t0 is None:
            self.t0 = time.monotonic_ns()
        rest = self.t0 + int(self.arrive_s[i] * 1e9) - time.monotonic_ns()
        if rest > 0:
            time.sleep(rest / 1e9)
        self.stats.frames += 1
        now = self.stamp() if self.stamp is not None else time.monotonic_ns() + self.ahead_ns
        return TimedFrame(self.frames[i % len(self.frames)], now, i, arrival_ns=now)

    def close(self) -> None:
        pass


def _runtime(free, model, sources, prewarm=True):
    sensors = []
    for k, src in enumerate(sources):
        g = ContactGate()
        g.capture_background([free])
        sensors.append(Sensor(f"s{k}", src, g))
    return ForceRuntime(sensors, model, RuntimeOptions(deadline_ms=1e6, prewarm=prewarm), owns_model=False)


def _steps(rt) -> list[tuple[int, bool]]:
    """Every reading's frame index and whether the step that made it ran or abandoned a
    warm-up before it."""
    out = []
    while not rt.finished:
        before = rt.stats.prewarms + rt.stats.prewarm_abandoned
        readings = rt.step()
        warmed = rt.stats.prewarms + rt.stats.prewarm_abandoned > before
        out += [(r.frame_index, warmed) for r in readings]
    return out


@pytest.mark.parametrize("prewarm", [True, False])
@pytest.mark.parametrize("clock", ["wall", "ahead"])
def test_a_stamp_of_another_clock_is_refused_at_the_first_frame(frames, model, clock, prewarm):
    """A replay stamped with the wall clock planned a rest of 57 years; a camera whose clock
    runs 0.3 s ahead made most frames stale. Both are refused at once, naming the sensor."""
    free, seq = frames
    cam = (ScriptedCamera(seq, [0.0] * 4, stamp=time.time_ns) if clock == "wall"
           else ScriptedCamera(seq, [0.0] * 4, ahead_ns=300_000_000))
    rt = _runtime(free, model, [cam], prewarm)
    try:
        with pytest.raises(SourceError, match=r"sensor 's0'.*TimedFrame.arrival_ns.*runtime's clock"):
            rt.step()
        assert rt.stats.readings == 0
    finally:
        rt.close()


def test_a_bursty_camera_frame_ends_the_rest(frames, model):
    """Frames in pairs 1 ms apart every 33 ms: the second of a pair never waits for a
    warm-up (before, 30 of 70 readings were late)."""
    free, seq = frames
    arrive = [k // 2 * 0.033 + (k % 2) * 0.001 for k in range(24)]
    rt = _runtime(free, model, [ScriptedCamera(seq, arrive)])
    try:
        got = _steps(rt)
    finally:
        rt.close()
    assert [i for i, _ in got] == list(range(24))  # every frame served, none stale
    assert not [i for i, warmed in got if i % 2 and warmed]


def test_a_jittery_camera_frame_that_comes_early_ends_the_rest(frames, model):
    """One frame in six 6 ms late: the next comes 6 ms before the cadence predicts it, during
    the rest, and is served without a warm-up before it (the first time; then the margin has
    learnt how early frames come); the warm-ups go on."""
    free, seq = frames
    period = 0.020
    arrive = [k * period + (0.006 if k % 6 == 5 else 0.0) for k in range(36)]
    rt = _runtime(free, model, [ScriptedCamera(seq, arrive)])
    try:
        got = _steps(rt)
        stats = rt.stats
    finally:
        rt.close()
    assert [i for i, _ in got] == list(range(36))
    assert stats.prewarms > 0
    assert dict(got)[6] is False


def test_a_frame_that_arrives_during_a_warm_up_abandons_it(frames, model, monkeypatch):
    """The camera is released from within the warm-up's first part (each sensor's gate pass):
    the warm-up gives up before the model call and the frame is served."""
    free, seq = frames
    gate_evt = threading.Event()
    calls = {"model": 0}

    class HeldCamera(FrameSource):
        """A fake camera: frames at 20 fps, but frame 8 only once a warm-up has begun."""

        name = "held"

        def __init__(self) -> None:
            super().__init__()
            self.t0 = 0

        def read(self):
            i = self.stats.frames
            if i >= 10:
                return None
            if i == 0:
                self.t0 = time.monotonic_ns()
            if i == 8:
                gate_evt.wait(5.0)
            else:
                rest = self.t0 + i * 50_000_000 - time.monotonic_ns()
                if rest > 0:
                    time.sleep(rest / 1e9)
            self.stats.frames += 1
            now = time.monotonic_ns()
            return TimedFrame(seq[2 + i % 4], now, i, arrival_ns=now)  # presses: the model is warmed too

        def close(self) -> None:
            gate_evt.set()

    from tactile_force.edge.runtime.gating import GateStep

    real_gate, real_model = GateStep.prewarm, model.prewarm

    def gate_prewarm(step) -> None:
        if step.gate is rt.sensors[0].gate and rt.stats.readings == 8 and not gate_evt.is_set():
            gate_evt.set()  # frame 8 arrives now, during the warm-up
            deadline = time.monotonic() + 5.0
            while not rt._warm.grabbers.ready(rt.sensors) and time.monotonic() < deadline:
                time.sleep(0.001)
        real_gate(step)

    def model_prewarm(n: int = 1) -> None:
        calls["model"] += 1
        real_model(n)

    monkeypatch.setattr(GateStep, "prewarm", gate_prewarm)
    monkeypatch.setattr(model, "prewarm", model_prewarm)
    rt = _runtime(free, model, [HeldCamera()])
    try:
        got = _steps(rt)
        stats = rt.stats
        released = gate_evt.is_set()  # by the warm-up (close() sets it too)
    finally:
        rt.close()
    assert [i for i, _ in got] == list(range(10))
    assert released and stats.prewarm_abandoned >= 1  # frame 8 came during a warm-up, given up
    assert calls["model"] == stats.prewarms  # the abandoned one never reached the model call


def test_the_prewarm_state_says_what_the_runtime_does(frames, model):
    free, seq = frames
    states = {}
    for mode in ("auto", True, False):
        rt = _runtime(free, model, [ListSource(seq[:3])], mode)
        rt.run()
        rt.close()
        states[mode] = rt.stats.prewarm
    assert states == {"auto": "trying", True: "on (RuntimeOptions.prewarm=True)",
                      False: "off (RuntimeOptions.prewarm=False)"}
    g = ContactGate()
    g.capture_background([free])
    rt = ForceRuntime([Sensor("s", ListSource(seq[:3]), g)], model, owns_model=False, clock=FakeClock(PERIOD))
    rt.close()
    assert rt.stats.prewarm.startswith("off (the runtime's clock is injected")
    rt = ForceRuntime([Sensor("s", ListSource(seq[:3]), g)], model, RuntimeOptions(grabbers=False), owns_model=False)
    rt.close()
    assert rt.stats.prewarm.startswith("off (RuntimeOptions.grabbers=False")


def test_one_sensor_goes_back_to_the_loops_thread_when_warm_ups_stop(frames, model):
    """One sensor gets a grabber thread while warm-ups run and reads in the loop's thread
    again while they do not (a decision on a fake clock flips every two steps): no frame is
    lost or repeated, every reading is the one made without warm-ups."""
    from tactile_force.edge.runtime.prewarm_decision import WINDOW_NS, PrewarmDecision

    free, seq = frames
    seq = seq[:24]
    want, _ = _run(seq, free, model, 1, prewarm=False, paced=False)
    rt = _runtime(free, model, [PacedList(seq, 50)], "auto")
    fake = FakeClock(0)
    rt._warm.decision = PrewarmDecision("auto", fake, cpu=lambda: 0)
    got, threads = [], []
    try:
        while not rt.finished:
            got += [(r.sensor, r.frame_index, r.force_n, int(r.flags), r.contact_area_px, r.detail) for r in rt.step()]
            threads.append(rt._warm.grabbers is not None)
            fake.t += WINDOW_NS // 2
    finally:
        rt.close()
    np.testing.assert_equal(sorted(got, key=lambda r: (r[0], r[1])), want)
    assert [r[1] for r in got] == list(range(len(seq)))
    first = threads.index(True)
    assert False in threads[first:]  # retired after warm-ups stopped
    assert True in threads[first + threads[first:].index(False):]  # and back for the next warm-ups


def test_once_auto_leaves_warm_ups_off_a_reading_runs_the_path_of_prewarm_false(frames, model):
    """After the 'auto' trial decides against warm-ups (a decision on a fake clock: too few
    readings to judge), until the next trial the runtime keeps nothing for a warm-up: no
    cadence is tracked, no last input held, no grabber thread runs; the readings are those
    made with warm-ups off. During settling and the trial it keeps them."""
    from tactile_force.edge.runtime.prewarm_decision import RETRY_NS, WINDOW_NS, PrewarmDecision

    free, seq = frames
    seq = (seq * 4)[:60]
    want, _ = _run(seq, free, model, 1, prewarm=False, paced=False)
    rt = _runtime(free, model, [PacedList(seq, 50)], "auto")
    fake = FakeClock(0)
    rt._warm.decision = PrewarmDecision("auto", fake, cpu=lambda: 0)
    seen = []
    real_seen = rt._warm.prewarm.seen
    rt._warm.prewarm.seen = lambda name, ns: (seen.append(ns), real_seen(name, ns))  # type: ignore[method-assign]
    got, phases = [], []
    try:
        while not rt.finished:
            n_seen = len(seen)
            out = rt.step()
            got += [(r.sensor, r.frame_index, r.force_n, int(r.flags), r.contact_area_px, r.detail) for r in out]
            lane = rt._lanes["s0"]
            phases.append((rt.stats.prewarm, rt._warm.watching, len(seen) - n_seen, lane.last is not None,
                           rt._warm.grabbers is not None))
            if not rt.stats.prewarm.startswith("off"):
                fake.t += WINDOW_NS // 2
    finally:
        rt.close()
    np.testing.assert_equal(sorted(got, key=lambda r: (r[0], r[1])), want)
    trying = [p for p in phases if p[0] == "trying"]
    off = [p for p in phases if p[0].startswith("off")]
    assert trying and off, phases
    assert all(p[1] for p in trying) and sum(p[2] for p in trying) > 0  # the trial tracks the cadence
    assert off[0][0].startswith("off (too few readings")
    assert all(not p[1] and p[2] == 0 and not p[3] for p in off), off  # nothing kept for a warm-up
    assert not off[-1][4]  # the grabber thread retired
    assert rt._warm.decision._next > fake.t + RETRY_NS // 2  # held until the next trial
