"""Arrival stamps and side-by-side sensors: every source stamps when it had a frame, the
runtime's ``late`` counts from that stamp (not from the frame's timestamp value), and two
sensors are read in their own grabber threads so one never waits for the other. Real ONNX
Runtime sessions and real DIGIT frames; the sources that block are fakes at the camera
boundary. No wall-clock assertions: ordering is forced with events."""

from __future__ import annotations

import threading

import cv2
import numpy as np
import pytest
from tactile_force.edge import Flags, SourceError, TimedFrame
from tactile_force.edge.frames import FrameSource
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
from tactile_force.edge.sources import CameraSource, ReplayFolderSource, load_background
from tactile_force.edge.synthetic import VirtualDigitSource

from tests.bridge.fakes import FakeCamera, landscape
from tests.conftest import FakeClock, shared_data

WAIT_S = 20.0  # generous: only a hung thread ever gets near it


def _gate() -> ContactGate:
    g = ContactGate()
    g.capture_background(load_background(shared_data("digit_backgrounds", "aurova_background_b.png")))
    return g


def _touch(aurova_dir) -> np.ndarray:
    return cv2.imread(str(aurova_dir / "images" / "1512.png"))


# -- arrival stamps ----------------------------------------------------------------------------
def test_file_sources_stamp_arrival(aurova_dir):
    clock = FakeClock(step_ns=1_000_000)
    unpaced = ReplayFolderSource(aurova_dir, clock=clock)
    a = unpaced.read()
    assert a.arrival_ns is not None and a.arrival_ns >= a.timestamp_ns  # decoded after it was stamped
    b = unpaced.read()
    assert b.arrival_ns > a.arrival_ns
    clock2 = FakeClock(step_ns=1_000_000)
    paced = ReplayFolderSource(aurova_dir, fps=100.0, clock=clock2, sleep=clock2.sleep)
    frames = [paced.read() for _ in range(3)]
    assert [f.arrival_ns for f in frames] == [f.timestamp_ns for f in frames]  # a paced frame arrives when due
    assert np.diff([f.arrival_ns for f in frames]).tolist() == [10_000_000, 10_000_000]


def test_camera_stamps_arrival_when_the_grab_returned(portraits):
    clock = FakeClock(step_ns=2_000_000)
    cam = FakeCamera([landscape(p) for p in portraits])
    with CameraSource(0, grab_thread=False, open_capture=lambda dev: cam, clock=clock) as src:
        before = clock.t
        f = src.read()
        assert f.arrival_ns == f.timestamp_ns and before < f.arrival_ns <= clock.t


def test_virtual_digit_renders_ahead_same_frames_and_stamps_arrival():
    ahead = VirtualDigitSource(seed=3, n_grasps=1, start_ns=0, render_ahead=3)
    inline = VirtualDigitSource(seed=3, n_grasps=1, start_ns=0, render_ahead=0)
    a, b = list(ahead), list(inline)
    assert len(a) == len(b) == len(ahead) and [f.index for f in a] == list(range(len(a)))
    for x, y in zip(a[::20], b[::20]):
        assert np.array_equal(x.frame, y.frame) and x.truth_n == y.truth_n and x.timestamp_ns == y.timestamp_ns
    arrivals = np.array([f.arrival_ns for f in a])
    assert np.all(np.diff(arrivals) >= 0)  # rendered in order, each stamped when it was ready
    ahead.close()
    assert ahead.read() is None
    with pytest.raises(ValueError, match="render_ahead"):
        VirtualDigitSource(render_ahead=-1)


class StampedSource(FrameSource):
    """Frames whose arrival stamp lies ``waited_ns`` before read() returns (a frame that sat in
    a driver buffer), with a timestamp value unrelated to the runtime's clock."""

    def __init__(self, frame: np.ndarray, clock: FakeClock, waited_ns: list[int], stamp: bool = True):
        super().__init__()
        self.frame, self.clock, self.waited, self.stamp = frame, clock, list(waited_ns), stamp

    def read(self) -> TimedFrame | None:
        if not self.waited:
            return None
        w = self.waited.pop(0)
        i = self.stats.frames
        self.stats.frames += 1
        return TimedFrame(self.frame, timestamp_ns=123 + i, index=i,  # a device counter, not our clock
                          arrival_ns=(self.clock.t - w) if self.stamp else None)


def test_late_counts_from_arrival_not_from_the_timestamp_value(rgb_bundle, aurova_dir):
    clock = FakeClock(step_ns=100_000)  # every clock read: 0.1 ms; one reading takes well under 2 ms
    src = StampedSource(_touch(aurova_dir), clock, [0, 30_000_000, 0])
    rt = ForceRuntime([Sensor("s", src, _gate())], OnnxForceModel(rgb_bundle), RuntimeOptions(deadline_ms=16.7),
                      clock=clock)
    fresh, waited, fresh2 = (rt.step()[0] for _ in range(3))
    assert not fresh.flags & Flags.LATE and fresh.latency.total_ms < 2.0
    assert waited.flags & Flags.LATE and waited.latency.total_ms >= 30.0  # it sat 30 ms before we had it
    assert not fresh2.flags & Flags.LATE
    # A source that stamps no arrival: latency from when read() returned, never guessed from the timestamp.
    clock2 = FakeClock(step_ns=100_000)
    plain = StampedSource(_touch(aurova_dir), clock2, [30_000_000], stamp=False)
    rt2 = ForceRuntime([Sensor("s", plain, _gate())], OnnxForceModel(rgb_bundle), clock=clock2)
    (r,) = rt2.step()
    assert not r.flags & Flags.LATE and r.latency.total_ms < 2.0


# -- two sensors side by side --------------------------------------------------------------------
class GatedCamera(FrameSource):
    """Camera-boundary fake: read() blocks until the test releases a frame (``release()``);
    ``reading`` is set while a read waits. ``fail`` makes the next released read raise.
    ``close()`` ends a blocked read (None), as releasing a real capture does."""

    def __init__(self, frame: np.ndarray, n: int):
        super().__init__()
        self.frame, self.left = frame, n
        self.go = threading.Semaphore(0)
        self.reading = threading.Event()
        self.error: BaseException | None = None
        self.closed = False

    def release(self, k: int = 1) -> None:
        for _ in range(k):
            self.go.release()

    def read(self) -> TimedFrame | None:
        self.reading.set()
        if not self.go.acquire(timeout=WAIT_S):
            raise RuntimeError("test fake: never released")
        self.reading.clear()
        if self.closed:
            return None
        if self.error is not None:
            raise self.error
        if self.left == 0:
            return None
        self.left -= 1
        i = self.stats.frames
        self.stats.frames += 1
        return TimedFrame(self.frame, i, i, arrival_ns=None)

    def close(self) -> None:
        self.closed = True
        self.go.release()  # a read blocked in its grabber thread returns


class ReadySource(FrameSource):
    """n frames, each there at once."""

    def __init__(self, frame: np.ndarray, n: int):
        super().__init__()
        self.frame, self.left = frame, n

    def read(self) -> TimedFrame | None:
        if self.left == 0:
            return None
        self.left -= 1
        i = self.stats.frames
        self.stats.frames += 1
        return TimedFrame(self.frame, i, i)


def test_one_sensor_is_served_while_the_other_blocks(rgb_bundle, aurova_dir):
    touch = _touch(aurova_dir)
    a, b = ReadySource(touch, 3), GatedCamera(touch, 1)
    rt = ForceRuntime([Sensor("a", a, _gate()), Sensor("b", b, _gate())], OnnxForceModel(rgb_bundle))
    got = []
    for _ in range(3):  # b's camera has not delivered a frame: a is served all the same
        got += rt.step()
    assert [r.sensor for r in got] == ["a", "a", "a"] and all(np.isfinite(r.force_n) for r in got)
    assert b.reading.is_set() and b.stats.frames == 0  # b's read is still blocked in its own thread
    b.release()
    later = []
    for _ in range(3):  # a step waits for a read; the one that takes a's end of stream gives no reading
        later = rt.step()
        if later:
            break
    (rb,) = later  # b's frame is served as soon as it is there
    assert rb.sensor == "b" and rb.frame_index == 0 and np.isfinite(rb.force_n)
    b.release()  # b's stream ends
    while not rt.finished:
        assert rt.step() == []
    assert rt.stats.readings == 4
    rt.close()


def test_both_sensors_with_frames_share_one_batch(rgb_bundle, aurova_dir):
    touch = _touch(aurova_dir)
    a, b = GatedCamera(touch, 2), GatedCamera(touch, 2)
    rt = ForceRuntime([Sensor("a", a, _gate()), Sensor("b", b, _gate())], OnnxForceModel(rgb_bundle))
    a.release(), b.release()
    assert rt.start(wait_s=WAIT_S)
    ra, rb = rt.step()
    assert (ra.sensor, rb.sensor) == ("a", "b")
    assert ra.latency.inference_ms == rb.latency.inference_ms and rt.stats.inferred == 2  # one predict, batch 2
    rt.close()


def test_grabber_errors_reach_the_loop(rgb_bundle, aurova_dir):
    touch = _touch(aurova_dir)
    a, b = GatedCamera(touch, 5), ReadySource(touch, 2)
    a.error = SourceError("camera /dev/video9: device disappeared (unplugged)")
    rt = ForceRuntime([Sensor("a", a, _gate()), Sensor("b", b, _gate())], OnnxForceModel(rgb_bundle))
    a.release()
    readings = []
    while not rt.finished:
        readings += rt.step()
    by = {s: [r for r in readings if r.sensor == s] for s in "ab"}
    assert len(by["a"]) == 1 and by["a"][0].flags & Flags.INVALID_INPUT and "unplugged" in by["a"][0].detail
    assert len(by["b"]) == 2 and all(np.isfinite(r.force_n) for r in by["b"])
    rt.close()
    # Anything else a source raises is not swallowed by its thread: step() raises it.
    c = GatedCamera(touch, 5)
    c.error = RuntimeError("driver bug")
    rt2 = ForceRuntime([Sensor("c", c, _gate()), Sensor("d", GatedCamera(touch, 1), _gate())],
                       OnnxForceModel(rgb_bundle))
    c.release()
    with pytest.raises(RuntimeError, match="driver bug"):
        rt2.step()
    rt2.close()  # ends d's read, still blocked in its grabber thread
