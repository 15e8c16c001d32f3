"""One runtime serving a whole hand: 8 sensors, their frames gated on two worker threads, one
batched predict for the frames that are ready together, each reading with its own sensor's
name, frame index and time stamp; a dead or blocked sensor holds up no other; batching and
the workers change no sensor's force. Real ONNX Runtime
sessions (the shipped default bundle), real gates and real DIGIT frames; the sources are
in-memory lists, fakes only where a camera would block or fail. No wall-clock assertions."""

from __future__ import annotations

import csv
import math
import threading

import cv2
import numpy as np
import pytest
from tactile_force.edge import Flags, SourceError
from tactile_force.edge.frames import MAX_BATCH
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
from tactile_force.edge.scene import build_scene, default_bundle_path, parse_scene, shipped_bundles
from tactile_force.edge.sources import load_background

from tests.conftest import ListSource, shared_data

N = 8
WAIT_S = 20.0  # generous: only a hung thread ever gets near it
# No `late` flags on a loaded machine (flags compared as made); a step's per-sensor work on two
# threads, as on a host with two cores (auto), whatever this host has.
OPTIONS = RuntimeOptions(deadline_ms=1e6, workers=2)


def _background_path():
    return shared_data("digit_backgrounds", "aurova_background_b.png")


def _gate(kind: type[ContactGate] = ContactGate) -> ContactGate:
    g = kind()
    g.capture_background(load_background(_background_path()))
    return g


@pytest.fixture(scope="module")
def hand_frames() -> list[list[np.ndarray]]:
    """Per sensor k: the 11 real AUROVA frames rotated by k, with the no-contact background
    at place k, so the sensors touch at different frames (batches of 1 to 8)."""
    images = shared_data("aurova_digit_grasp", "images")
    touch = [cv2.imread(str(p)) for p in sorted(images.glob("*.png"))]
    (free,) = load_background(_background_path())
    out = []
    for k in range(N):
        frames = touch[k:] + touch[:k]
        frames.insert(k, free)
        out.append(frames)
    return out


@pytest.fixture(scope="module")
def model():
    m = OnnxForceModel(default_bundle_path())
    yield m
    m.close()


def _stamp(k: int, i: int) -> int:
    """Sensor k's frame i time stamp (ns): its own clock, 60 fps."""
    return (k + 1) * 1_000_000_000 + i * 16_666_667


class StampedList(ListSource):
    """A ListSource whose frames carry the sensor's own time stamps; ``fail_at``: read()
    raises SourceError instead of returning that frame (a camera unplugged mid-run)."""

    def __init__(self, frames, k: int, fail_at: int | None = None) -> None:
        super().__init__(frames)
        self.k, self.fail_at = k, fail_at

    def read(self):
        i = self.stats.frames
        if i == self.fail_at:
            raise SourceError(f"camera of sensor {self.k}: device disappeared (unplugged)")
        tf = super().read()
        if tf is not None:
            tf.timestamp_ns = _stamp(self.k, i)
        return tf


class BlockedCamera(ListSource):
    """Camera-boundary fake: read() blocks until ``go`` is set, then the stream ends."""

    def __init__(self) -> None:
        super().__init__([])
        self.go = threading.Event()
        self.reading = threading.Event()

    def read(self):
        self.reading.set()
        if not self.go.wait(WAIT_S):
            raise RuntimeError("test fake: never released")
        return None


def _names() -> list[str]:
    return [f"finger{k}" for k in range(N)]


def _hand(model, hand_frames, gate=ContactGate, **fail) -> ForceRuntime:
    sensors = [Sensor(name, StampedList(hand_frames[k], k, fail.get(name)), _gate(gate))
               for k, name in enumerate(_names())]
    rt = ForceRuntime(sensors, model, OPTIONS, owns_model=False)
    assert rt.workers == 2
    return rt


def _run_all(rt: ForceRuntime) -> tuple[list, list[list]]:
    """(every reading, the readings of each step) until every source ended."""
    assert rt.start(wait_s=WAIT_S)  # every grabber has its first frame: the first step serves all 8
    steps = []
    while not rt.finished:
        steps.append(rt.step())
    rt.close()
    return [r for s in steps for r in s], steps


def _by_sensor(readings) -> dict[str, list]:
    return {name: [r for r in readings if r.sensor == name] for name in _names()}


def test_eight_sensors_one_reading_per_frame_in_order_with_their_name(model, hand_frames):
    rt = _hand(model, hand_frames)
    readings, steps = _run_all(rt)
    by = _by_sensor(readings)
    for k, name in enumerate(_names()):
        got = by[name]
        assert [r.frame_index for r in got] == list(range(12)), name
        assert [r.timestamp_ns for r in got] == [_stamp(k, i) for i in range(12)], name
        assert got[k].flags & Flags.NO_CONTACT and got[k].force_n == 0.0  # its no-contact frame
        assert all(math.isfinite(r.force_n) and not r.flags & Flags.STALE for r in got)
    assert len(readings) == rt.stats.readings == N * 12 and rt.stats.inferred == N * 11
    # The first step served all eight; the seven in contact went to the model in one call.
    first = steps[0]
    assert sorted(r.sensor for r in first) == _names()
    touching = [r for r in first if not r.flags & Flags.NO_CONTACT]
    assert len(touching) == N - 1 and len({r.latency.inference_ms for r in touching}) == 1


@pytest.mark.parametrize("bundle", ["default", "d", "rgbmod_d"])  # RGB, depth, RGB + depth: every batch buffer
def test_a_batched_call_gives_each_sensor_the_force_it_gives_alone(bundle, hand_frames):
    model = OnnxForceModel(shipped_bundles()[bundle])
    together, steps = _run_all(_hand(model, hand_frames))
    assert max(sum(not r.flags & Flags.NO_CONTACT for r in s) for s in steps) > 2  # batches beyond a pair
    by = _by_sensor(together)
    for k, name in enumerate(_names()):
        alone = ForceRuntime([Sensor(name, StampedList(hand_frames[k], k), _gate())], model, OPTIONS,
                             owns_model=False)
        assert alone.workers == 1  # one sensor: the loop's thread only
        solo = []
        while not alone.finished:
            solo += alone.step()
        alone.close()
        assert [r.force_n for r in by[name]] == [r.force_n for r in solo], name  # bit for bit
        assert [r.flags for r in by[name]] == [r.flags for r in solo], name
        assert [(r.force_low_n, r.force_high_n) for r in by[name]] == [(r.force_low_n, r.force_high_n) for r in solo]
    model.close()


class MeetingGate(ContactGate):
    """A real gate whose first update waits (up to WAIT_S) until another sensor's gate is in
    its first update too: only two threads gating at once get past it."""

    meet = threading.Barrier(2, timeout=WAIT_S)  # on the class: no gate holds it (parts are their own)
    met: set[str] = set()

    def update(self, frame):
        if not getattr(self, "_met", False):
            self._met = True
            MeetingGate.meet.wait()  # BrokenBarrierError when no second thread ever comes
            MeetingGate.met.add(threading.current_thread().name)
        return super().update(frame)


def test_frames_ready_together_are_gated_on_two_threads_and_batched_once(model, hand_frames):
    rt = _hand(model, hand_frames, gate=MeetingGate)
    readings, steps = _run_all(rt)
    assert len(MeetingGate.met) == 2 and threading.current_thread().name in MeetingGate.met  # the loop and a worker
    touching = [r for r in steps[0] if not r.flags & Flags.NO_CONTACT]
    assert len(touching) == N - 1 and len({r.latency.inference_ms for r in touching}) == 1  # still one predict
    by = _by_sensor(readings)
    for k, name in enumerate(_names()):
        assert [(r.frame_index, r.timestamp_ns) for r in by[name]] == [(i, _stamp(k, i)) for i in range(12)], name
    mine = f"work-{'-'.join(_names())[:40]}-"
    assert not [t for t in threading.enumerate() if t.name.startswith(mine)]  # close() ended the workers


def test_a_dead_sensor_ends_alone(model, hand_frames):
    rt = _hand(model, hand_frames, finger3=5)  # finger3's camera is unplugged at its sixth frame
    readings, _ = _run_all(rt)
    by = _by_sensor(readings)
    dead = by["finger3"]
    assert [r.frame_index for r in dead[:5]] == list(range(5)) and len(dead) == 6
    assert dead[5].flags & Flags.INVALID_INPUT and "unplugged" in dead[5].detail and math.isnan(dead[5].force_n)
    assert not rt.sensors[3].alive and "unplugged" in rt.sensors[3].error
    for name in _names():
        if name != "finger3":  # every other sensor is served to its last frame
            assert [r.frame_index for r in by[name]] == list(range(12)), name
    assert rt.stats.source_errors == 1


def test_a_blocked_sensor_holds_up_no_other(model, hand_frames):
    blocked = BlockedCamera()
    sensors = [Sensor(name, StampedList(hand_frames[k], k), _gate()) for k, name in enumerate(_names()[:-1])]
    sensors.append(Sensor("stuck", blocked, _gate()))
    rt = ForceRuntime(sensors, model, OPTIONS, owns_model=False)
    readings = []
    while any(s.alive for s in sensors[:-1]):  # the seven others run to their end ...
        readings += rt.step()
    assert blocked.reading.is_set() and not blocked.go.is_set()  # ... while "stuck" is still in its read()
    by = _by_sensor(readings)
    assert all([r.frame_index for r in by[name]] == list(range(12)) for name in _names()[:-1])
    assert not [r for r in readings if r.sensor == "stuck"]
    blocked.go.set()  # its stream ends
    while not rt.finished:
        assert rt.step() == []
    rt.close()


def test_sixteen_frames_in_one_predict_each_as_alone(model, hand_frames):
    frames = np.stack([f for fs in hand_frames[:2] for f in fs[:8]])  # 16 real frames
    assert len(frames) == MAX_BATCH
    together = model.predict(frames)
    alone = np.array([model.predict(f[None])[0] for f in frames])
    assert together.shape == (MAX_BATCH,) and np.array_equal(together, alone)
    assert np.array_equal(model.predict(frames[:5]), alone[:5])  # a batch bound on first use, reused


def test_a_scene_with_eight_sensors_builds_and_runs(tmp_path, aurova_dir):
    out = tmp_path / "hand.csv"
    data = {"runtime": {"bundle": "default", "deadline_ms": 1e6},
            "sensor": [{"name": name, "source": "replay", "path": str(aurova_dir),
                        "background": str(_background_path())} for name in _names()],
            "output": [{"kind": "csv", "path": str(out)}]}
    scene = parse_scene(data, None, tmp_path)
    built = build_scene(scene)
    rt = built.runtime
    assert [s.name for s in rt.sensors] == _names() and len(built.sinks) == 1
    try:
        rt.run(built.sinks)
    finally:
        built.close()
    assert rt.stats.readings == N * 11 and rt.stats.source_errors == 0
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    for name in _names():
        assert [int(r["frame_index"]) for r in rows if r["sensor"] == name] == list(range(11)), name


def test_more_sensors_than_one_runtime_serves_are_refused(model):
    with pytest.raises(ValueError, match=r"17 sensors; expected 1 to 16"):
        ForceRuntime([Sensor(f"s{k}", ListSource([]), ContactGate()) for k in range(MAX_BATCH + 1)], model)
    rt = ForceRuntime([Sensor(f"s{k}", ListSource([]), ContactGate()) for k in range(MAX_BATCH)], model,
                      owns_model=False)
    assert len(rt.sensors) == MAX_BATCH
    rt.close()

