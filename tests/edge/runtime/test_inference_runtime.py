"""OnnxForceModel and ForceRuntime with real ONNX Runtime sessions on real files."""

from __future__ import annotations

import json
import math
import shutil

import cv2
import numpy as np
import pytest
from tactile_force.edge import BundleError, Flags, FrameError, SourceError, TimedFrame
from tactile_force.edge.frames import FrameSource
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.ladder import choose_bundle
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.outputs import CsvWriter, JsonlWriter
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor, plan_stages
from tactile_force.edge.sources import ReplayFolderSource, load_background
from tests.conftest import FakeClock, expected_force, shared_data


def _bg():
    return load_background(shared_data("digit_backgrounds", "aurova_background_b.png"))


def _gate():
    g = ContactGate()
    g.capture_background(_bg())
    return g


# -- inference ------------------------------------------------------------------------------
def test_predict_batch_one_and_two(rgb_bundle, aurova_dir):
    model = OnnxForceModel(rgb_bundle, threads=1)
    a = cv2.imread(str(aurova_dir / "images" / "1500.png"))
    b = cv2.imread(str(aurova_dir / "images" / "1524.png"))
    one = model.predict(a[None])
    two = model.predict(np.stack([a, b]))
    assert one.shape == (1,) and two.shape == (2,) and two.dtype == np.float32
    assert two[0] == pytest.approx(one[0], abs=1e-5)
    assert two[1] == pytest.approx(expected_force(b), abs=1e-3)


def test_predict_rejects_bad_input(rgb_bundle):
    model = OnnxForceModel(rgb_bundle)
    ok = np.zeros((1, 320, 240, 3), np.uint8)
    with pytest.raises(FrameError, match=r"shape \(1, 240, 320, 3\)"):
        model.predict(np.zeros((1, 240, 320, 3), np.uint8))
    with pytest.raises(FrameError, match="dtype float32 and contains NaN"):
        model.predict(np.full(ok.shape, np.nan, np.float32))
    with pytest.raises(FrameError, match="empty"):
        model.predict(np.zeros((0, 320, 240, 3), np.uint8))
    with pytest.raises(FrameError, match=r"batch 17; this model takes 1\.\.16 frames per call"):
        model.predict(np.zeros((17, 320, 240, 3), np.uint8))
    assert model.predict(ok).shape == (1,)


def test_bundle_with_wrong_hash_is_refused(rgb_bundle, tmp_path):
    bad = tmp_path / "tampered"
    shutil.copytree(rgb_bundle, bad)
    data = bytearray((bad / "model.onnx").read_bytes())
    data[-1] ^= 0xFF
    (bad / "model.onnx").write_bytes(bytes(data))
    with pytest.raises(BundleError, match="does not match the manifest"):
        OnnxForceModel(bad)


def test_manifest_that_does_not_match_the_graph_is_refused(rgb_bundle, tmp_path):
    bad = tmp_path / "renamed"
    shutil.copytree(rgb_bundle, bad)
    man = json.loads((bad / "model.json").read_text())
    man["inputs"][0]["name"] = "image"
    (bad / "model.json").write_text(json.dumps(man))
    with pytest.raises(BundleError, match=r"renamed: .*graph input 'rgb' is not a manifest input \(declared: \['image'\]\)"):
        OnnxForceModel(bad)


# -- runtime --------------------------------------------------------------------------------
def test_replay_of_real_aurova_frames(rgb_bundle, aurova_dir):
    src = ReplayFolderSource(aurova_dir)
    rt = ForceRuntime([Sensor("left", src, _gate())], OnnxForceModel(rgb_bundle))
    assert rt.stages == ["source:left", "gate:left", "inference:cpu"]
    stats = rt.run()
    assert stats.readings == 11 and stats.inferred == 11 and stats.no_contact == 0
    assert rt.sensors[0].depth is None


def test_readings_forces_flags_and_latency(rgb_bundle, aurova_dir):
    rt = ForceRuntime([Sensor("left", ReplayFolderSource(aurova_dir), _gate())], OnnxForceModel(rgb_bundle))
    readings = [r for _ in range(11) for r in rt.step()]
    assert [r.frame_index for r in readings] == list(range(11))
    for r in readings:
        assert r.flags & ~Flags.LATE == Flags.NONE
        assert math.isfinite(r.force_n) and r.truth_n is not None
        lat = r.latency
        assert lat.total_ms >= lat.gate_ms + lat.inference_ms > 0
    img = cv2.imread(str(aurova_dir / "images" / "1500.png"))
    assert readings[0].force_n == pytest.approx(expected_force(img), abs=1e-3)
    assert readings[0].truth_n == pytest.approx(1.0813515)
    p = rt.latency()
    assert set(p) == {"source", "gate", "depth", "inference", "total"} and p["total"]["p99"] >= p["total"]["p50"]


def test_no_contact_skips_cnn_and_range_flags(make_bundle, aurova_dir):
    bg = _bg()[0]
    touch = cv2.imread(str(aurova_dir / "images" / "1512.png"))
    frames = [bg, touch]

    class ListSource(FrameSource):
        def __init__(self, items):
            super().__init__()
            self.items = list(items)

        def read(self):
            if not self.items:
                return None
            f = self.items.pop(0)
            self.stats.frames += 1
            return TimedFrame(f, 0, self.stats.frames - 1)

    low = OnnxForceModel(make_bundle("low", scale=1.0))  # ~0.4 N
    rt = ForceRuntime([Sensor("s", ListSource(frames), _gate())], low)
    r0, r1 = rt.step() + rt.step()
    assert r0.flags & Flags.NO_CONTACT and r0.force_n == 0.0 and math.isnan(r0.raw_force_n)
    assert rt.stats.inferred == 1
    assert r1.flags & Flags.BELOW_RANGE and 0.0 <= r1.force_n < 1.0
    high = OnnxForceModel(make_bundle("high", scale=60.0))  # ~23 N
    rt = ForceRuntime([Sensor("s", ListSource([touch]), _gate())], high)
    (r,) = rt.step()
    assert r.flags & Flags.SATURATED and r.force_n == 15.0 and r.raw_force_n > 15.0


class FakeCameraUnplugged(FrameSource):
    """Hardware-boundary fake: a camera that delivers real frames, then disappears."""

    def __init__(self, frames, fail_after: int):
        super().__init__()
        self.frames, self.fail_after = frames, fail_after

    def read(self):
        if self.stats.frames >= self.fail_after:
            raise SourceError("camera /dev/video7: device disappeared (unplugged)")
        f = self.frames[self.stats.frames % len(self.frames)]
        self.stats.frames += 1
        return TimedFrame(f, 0, self.stats.frames - 1)


class FakeCameraBadFrames(FrameSource):
    """Hardware-boundary fake: a driver that hands over malformed buffers."""

    def __init__(self, frames):
        super().__init__()
        self.frames = list(frames)

    def read(self):
        if not self.frames:
            return None
        self.stats.frames += 1
        return TimedFrame(self.frames.pop(0), 0, self.stats.frames - 1)


def test_unplugged_camera_and_bad_frames_keep_other_sensor_and_files(rgb_bundle, aurova_dir, tmp_path):
    touch = cv2.imread(str(aurova_dir / "images" / "1510.png"))
    left = Sensor("left", FakeCameraUnplugged([touch], fail_after=3), _gate())
    bad = [np.zeros((240, 320, 3), np.uint8), np.full((320, 240, 3), np.nan, np.float32),
           np.zeros((0, 240, 3), np.uint8), np.zeros((320, 240, 3), np.uint8), touch, touch, touch]
    right = Sensor("right", FakeCameraBadFrames(bad), _gate())
    rt = ForceRuntime([left, right], OnnxForceModel(rgb_bundle))
    csv_path, jsonl_path = tmp_path / "r.csv", tmp_path / "r.jsonl"
    sinks = [CsvWriter(csv_path), JsonlWriter(jsonl_path)]
    rt.run(sinks)  # no close: what was written must already be on disk
    rows = [json.loads(line) for line in jsonl_path.read_text().splitlines()]
    csv_rows = csv_path.read_text().splitlines()
    assert len(csv_rows) == len(rows) + 1 == rt.stats.readings + 1
    by = {"left": [r for r in rows if r["sensor"] == "left"], "right": [r for r in rows if r["sensor"] == "right"]}
    assert [r["flags"] for r in by["left"][:3]] == ["", "", ""]
    assert by["left"][3]["flags"] == "invalid_input" and "unplugged" in by["left"][3]["detail"]
    right_flags = [r["flags"] for r in by["right"]]
    assert right_flags[:4] == ["invalid_input"] * 4
    details = [r["detail"] for r in by["right"][:4]]
    assert "landscape" in details[0] and "NaN" in details[1] and "empty" in details[2] and "all-dark" in details[3]
    assert right_flags[4:] == ["", "", ""]  # served after the left camera was gone
    assert all(r["force_n"] is None for r in by["right"][:4])
    assert rt.stats.source_errors == 1 and rt.stats.invalid == 5
    for s in sinks:
        s.close()
    rt.close()


def test_two_sensors_in_contact_share_one_batch(rgb_bundle, aurova_dir):
    a = ReplayFolderSource(aurova_dir)
    b = ReplayFolderSource(aurova_dir)
    rt = ForceRuntime([Sensor("left", a, _gate()), Sensor("right", b, _gate())], OnnxForceModel(rgb_bundle))
    assert rt.start(wait_s=10.0)  # both grabber threads have a frame: one step serves both
    rl, rr = rt.step()
    assert rl.sensor == "left" and rr.sensor == "right"
    assert rl.latency.inference_ms == rr.latency.inference_ms  # one predict call, batch 2
    assert rl.force_n == pytest.approx(rr.force_n, abs=1e-5)
    rt.close()


def test_stale_and_late_with_a_fake_clock(rgb_bundle, aurova_dir):
    # Frames due every 10 ms; every clock read costs 3 ms, so one step (~6 reads) outlasts a frame.
    clock = FakeClock(step_ns=3_000_000)
    src = ReplayFolderSource(aurova_dir, fps=100.0, clock=clock, sleep=clock.sleep)
    rt = ForceRuntime([Sensor("s", src, _gate())], OnnxForceModel(rgb_bundle),
                      RuntimeOptions(deadline_ms=5.0), clock=clock)
    readings = []
    while not rt.finished:
        readings += rt.step()
    stale = [r for r in readings if r.flags & Flags.STALE]
    done = [r for r in readings if not r.flags & Flags.STALE]
    assert stale and done
    # Every frame accounted for exactly once, newest-first processing never goes backwards.
    assert sorted(r.frame_index for r in readings) == list(range(11))
    assert [r.frame_index for r in done] == sorted(r.frame_index for r in done)
    assert all(math.isnan(r.force_n) and "superseded" in r.detail for r in stale)
    assert rt.stats.stale == len(stale) == src.stats.dropped
    assert all(r.flags & Flags.LATE for r in done) and rt.stats.late == len(done)
    # Same timing with a generous deadline: nothing late.
    clock2 = FakeClock(step_ns=3_000_000)
    src2 = ReplayFolderSource(aurova_dir, fps=100.0, clock=clock2, sleep=clock2.sleep)
    rt2 = ForceRuntime([Sensor("s", src2, _gate())], OnnxForceModel(rgb_bundle),
                       RuntimeOptions(deadline_ms=100.0), clock=clock2)
    stats = rt2.run()
    assert stats.late == 0 and stats.stale == rt.stats.stale


def test_unpaced_replay_has_no_stale_frames(rgb_bundle, aurova_dir):
    clock = FakeClock(step_ns=50_000_000)
    src = ReplayFolderSource(aurova_dir, clock=clock)
    stats = ForceRuntime([Sensor("s", src, _gate())], OnnxForceModel(rgb_bundle), clock=clock).run()
    assert stats.stale == 0 and stats.processed == 11


def test_depth_bundles_plan_a_depth_stage(make_bundle):
    assert plan_stages(["l", "r"], needs_depth=True) == [
        "source:l", "gate:l", "depth:l", "source:r", "gate:r", "depth:r", "inference:cpu"]
    assert "depth:l" not in plan_stages(["l"], needs_depth=False)
    model = OnnxForceModel(make_bundle("mean_d", variant="d"))
    assert model.needs_depth
    with pytest.raises(FrameError, match="needs a depth image"):
        model.predict(np.zeros((1, 320, 240, 3), np.uint8))
    out = model.predict(np.zeros((1, 320, 240, 3), np.uint8), np.full((1, 320, 240, 1), 255, np.uint8))
    assert out[0] == pytest.approx(5.0, abs=1e-4)


def test_corrupt_replay_frames_are_counted_not_passed(tmp_path, aurova_dir):
    folder = tmp_path / "plain"
    folder.mkdir()
    shutil.copy(aurova_dir / "images" / "1500.png", folder / "frame_2.png")
    shutil.copy(aurova_dir / "images" / "1502.png", folder / "frame_10.png")
    (folder / "frame_5.png").write_bytes(b"\x89PNG truncated")
    src = ReplayFolderSource(folder)
    got = list(src)
    assert [tf.meta["path"].split("/")[-1] for tf in got] == ["frame_2.png", "frame_10.png"]
    assert src.stats.corrupt == 1 and src.stats.frames == 2
    assert all(tf.truth_n is None for tf in got)


def test_depth_bundle_runs_the_real_depth_stage_with_the_gate_mask(make_bundle, aurova_dir):
    from tactile_force.edge.runtime import build_depth_stage
    from tactile_force.edge.scene import DepthSettings

    mapping = shared_data("aurova_digit_depth_mlp.npz")
    model = OnnxForceModel(make_bundle("mean_dmod", variant="dmod"))
    rt = ForceRuntime([Sensor("s", ReplayFolderSource(aurova_dir), _gate())], model,
                      depth_factory=lambda: build_depth_stage(DepthSettings(mapping=mapping)))
    assert rt.stages == ["source:s", "gate:s", "depth:s", "inference:cpu"]
    readings = []
    while not rt.finished:
        readings += rt.step()
    assert len(readings) == 11
    ok = [r for r in readings if not r.flags & Flags.INVALID_INPUT]
    assert ok, [r.detail for r in readings]
    assert all(r.latency.depth_ms > 0 for r in ok)
    # The Dmod graph reads only the depth image: 5 N * mean(depth)/255, > 0 for a pressed gel.
    assert readings[-1].raw_force_n > 0.0
    assert readings[-1].raw_force_n > readings[0].raw_force_n  # deeper press at the end of the grasp


def test_depth_bundle_without_mapping_is_a_clear_scene_error():
    from tactile_force.edge import SceneError
    from tactile_force.edge.runtime import build_depth_stage
    from tactile_force.edge.scene import DepthSettings

    with pytest.raises(SceneError, match=r"depth\.mapping: missing; a depth bundle needs the colour->normal \.npz"):
        build_depth_stage(DepthSettings())
