"""One downscale per frame, shared by the gate and the model (real ONNX Runtime,
real OpenCV, the shipped default bundle and the c1733e6 reference graph kept as a format-2
bundle)."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from tactile_force.edge import BundleError, ContactGate, OnnxForceModel, load_bundle
from tactile_force.edge.bundle.manifest import FORMAT_VERSION, FrameReduction, Reduction, manifest_from_json
from tactile_force.edge.errors import FrameError
from tactile_force.edge.frames import FRAME_SHAPE
from tactile_force.edge.gate.frame_work import FrameWork
from tactile_force.edge.gate.reduce import FrameReducer, default_reduction, reduce_frames
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
from tactile_force.edge.scene import default_bundle_path

from tests.conftest import (
    REPO,  # noqa: E402
    ListSource,
)

REFERENCE = REPO / "benchmarks" / "reference_graphs" / "default_c1733e6.onnx"


def _frames(n: int = 4, seed: int = 0) -> np.ndarray:
    from tactile_force.edge.synthetic import ContactSpec, VirtualDigit, VirtualDigitOptions

    digit = VirtualDigit(VirtualDigitOptions(seed=seed))
    return np.stack([digit.render(ContactSpec("sphere_4mm" if i % 2 else "cylinder_8mm"), 4.0 + 2 * i).frame
                     for i in range(n)])


def _background() -> np.ndarray:
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    return VirtualDigit(VirtualDigitOptions(seed=0)).render(None, 0.0).frame


def test_reductions_are_exact_box_averages():
    f = np.random.default_rng(1).integers(0, 256, (2, 320, 240, 3), dtype=np.uint8)
    s = f.reshape(2, 80, 4, 60, 4, 3).astype(np.int64).sum((2, 4))
    area = reduce_frames(f, FrameReduction(Reduction.AREA, 4))
    assert np.array_equal(area, np.round(s / 16.0))  # ties to even: what the reference graph's quantizer did
    s2 = f.reshape(2, 160, 2, 120, 2, 3).astype(np.int64).sum((2, 4))
    half = (s2 + 2) >> 2
    steps = ((half.reshape(2, 80, 2, 60, 2, 3).sum((2, 4)) + 2) >> 2).astype(np.uint8)
    assert np.array_equal(reduce_frames(f, FrameReduction(Reduction.AREA_2X_STEPS, 4)), steps)
    assert np.abs(area.astype(int) - steps).max() <= 1
    assert default_reduction(4) == FrameReduction(Reduction.AREA_2X_STEPS, 4)
    assert default_reduction(1).method is Reduction.NONE and default_reduction(5).method is Reduction.AREA
    depth = f[..., :1].copy()
    assert reduce_frames(depth, default_reduction(4)).shape == (2, 80, 60, 1)


def test_default_bundle_starts_at_the_network_resolution():
    m = load_bundle(default_bundle_path()).manifest
    assert m.format_version == FORMAT_VERSION == 3
    (spec,) = m.inputs
    assert spec.shape == [-1, 80, 60, 3] and spec.layout == "NHWC" and spec.colour_order == "BGR"
    assert spec.reduction == FrameReduction(Reduction.AREA_2X_STEPS, 4)
    from tactile_force.edge.bundle.graph_facts import graph_facts

    assert "AveragePool" not in graph_facts(default_bundle_path() / "model.onnx").ops  # the shrink left the graph
    assert m.error.vs_truth.re_mean <= 0.08


def test_predict_on_full_frames_equals_predict_on_the_reduced_image():
    model = OnnxForceModel(default_bundle_path())
    frames = _frames(2)
    reduced = reduce_frames(frames, model.reduction)
    full = model.predict(frames)
    assert np.array_equal(full, model.predict_reduced(reduced))
    assert np.array_equal(full[:1], model.predict_reduced(reduced[:1]))
    with pytest.raises(FrameError, match=r"\(N, 80, 60, 3\)"):
        model.predict_reduced(frames)  # full frames are not a reduced image
    with pytest.raises(FrameError, match=r"\(N, 320, 240, 3\)"):
        model.predict(reduced)


def test_format2_bundle_still_loads_and_gives_the_same_forces(tmp_path):
    """The c1733e6 default (format 2, full-resolution graph) loads as reduction none; the new
    default fed frames reduced by 'area' is the same graph to the last bit."""
    raw = json.loads(REFERENCE.with_suffix(".json").read_text())
    assert raw["format_version"] == 2
    m = manifest_from_json(raw)
    assert m.format_version == 3 and m.inputs[0].reduction == FrameReduction()
    assert m.inputs[0].shape[1:] == [320, 240, 3]
    shutil.copy(REFERENCE, tmp_path / "old.onnx")
    shutil.copy(REFERENCE.with_suffix(".json"), tmp_path / "old.json")
    old = OnnxForceModel(tmp_path / "old.onnx")
    assert old.reduction.method is Reduction.NONE and old.rgb_shape == (320, 240, 3)
    frames = _frames(2)
    f_old = old.predict(frames)
    assert np.array_equal(f_old, old.predict_reduced(frames))  # a full-resolution graph: same path
    onnx = pytest.importorskip("onnx", reason="graph surgery needs the export extra")
    pytest.importorskip("torch", reason="tactile_force.export needs the export extra (torch)")
    assert onnx
    from tactile_force.export.network_input import network_input_bundle

    exact = network_input_bundle(tmp_path / "old.onnx", tmp_path / "cut", FrameReduction(Reduction.AREA, 4))
    assert np.array_equal(OnnxForceModel(exact).predict(frames), f_old)


def test_graph_contract_follows_the_network_input_record(tmp_path):
    b = load_bundle(default_bundle_path())
    raw = json.loads((b.path / "model.json").read_text())
    raw["inputs"][0]["shape"] = [-1, 320, 240, 3]
    raw["inputs"][0]["reduction"] = {"method": "none", "factor": 1}
    shutil.copytree(b.path, tmp_path / "lie")
    (tmp_path / "lie" / "model.json").write_text(json.dumps(raw))
    # refused at load (the graph's facts, as bundle verify reads them), before ONNX Runtime
    with pytest.raises(BundleError, match=r"lie: .*inputs\['rgb'\]\.reduction none x1 makes 320 x 240 images, but "
                                          r"graph input 'rgb' is 80 x 60"):
        OnnxForceModel(tmp_path / "lie")
    raw["inputs"][0]["reduction"] = {"method": "none", "factor": 4}
    (tmp_path / "lie" / "model.json").write_text(json.dumps(raw))
    with pytest.raises(BundleError, match="'none' goes with factor 1"):
        load_bundle(tmp_path / "lie")


class _Watch:
    """The real OnnxForceModel, recording what the runtime hands it (no fake inference)."""

    def __init__(self, model: OnnxForceModel) -> None:
        self.model = model
        self.seen: list[tuple[str, np.ndarray]] = []
        self.bundle, self.reduction, self.rgb_shape = model.bundle, model.reduction, model.rgb_shape
        self.needs_depth, self.calibration = model.needs_depth, model.calibration

    @property
    def closed(self) -> bool:
        return self.model.closed

    def predict(self, rgb, depth=None):
        self.seen.append(("full", rgb.copy()))  # the runtime hands views of buffers reused next frame
        return self.model.predict(rgb, depth)

    def predict_reduced(self, rgb, depth=None):
        self.seen.append(("reduced", rgb.copy()))
        return self.model.predict_reduced(rgb, depth)

    def close(self) -> None:
        self.model.close()


@pytest.mark.parametrize("sensors", [1, 2])
def test_one_downscale_per_frame_shared_by_gate_and_model(monkeypatch, sensors):
    calls = {"n": 0}
    real = FrameReducer.__call__
    real_work = FrameWork.reduce

    def counted(self, frame, out=None):
        calls["n"] += 1
        return real(self, frame, out)

    def counted_work(self, frame, blur=False, noise=False):  # the gate's reduction (no FrameReducer call)
        calls["n"] += 1
        return real_work(self, frame, blur, noise)

    monkeypatch.setattr(FrameReducer, "__call__", counted)
    monkeypatch.setattr(FrameWork, "reduce", counted_work)
    model = OnnxForceModel(default_bundle_path())
    watch = _Watch(model)
    frames = _frames(6)
    gates, sens = [], []
    for k in range(sensors):
        g = ContactGate()
        g.capture_background([_background()])
        gates.append(g)
        sens.append(Sensor(f"s{k}", ListSource(frames), g))
    seen_by_gate: list[np.ndarray] = []
    orig_update = ContactGate.update

    def spy(self, frame):
        r = orig_update(self, frame)
        seen_by_gate.append(r.reduced.copy())
        return r

    monkeypatch.setattr(ContactGate, "update", spy)
    rt = ForceRuntime(sens, watch, RuntimeOptions(deadline_ms=1e9, grabbers=False, workers=1))  # gate spies in order
    calls["n"] = 0
    readings: list = []
    rt.run(on_reading=readings.append)
    assert rt.stats.processed == sensors * len(frames) and rt.stats.inferred == sensors * len(frames)
    assert calls["n"] == sensors * len(frames)  # one downscale per frame, nothing else reduced
    assert [kind for kind, _ in watch.seen] == ["reduced"] * len(frames)  # one batched call per step
    handed = np.concatenate([x for _, x in watch.seen])
    assert handed.shape[1:] == (80, 60, 3)
    assert np.array_equal(handed, np.stack(seen_by_gate))  # the gate's image is the model's input
    assert np.array_equal(np.stack(seen_by_gate)[::sensors], reduce_frames(frames, model.reduction))
    forces = np.array([r.raw_force_n for r in readings])
    per_frame = np.concatenate([model.predict(frames[i:i + 1]) for i in range(len(frames))])
    assert np.allclose(forces, np.repeat(per_frame, sensors), atol=1e-5)


def test_full_resolution_bundles_keep_their_path(tmp_path):
    shutil.copy(REFERENCE, tmp_path / "old.onnx")
    shutil.copy(REFERENCE.with_suffix(".json"), tmp_path / "old.json")
    watch = _Watch(OnnxForceModel(tmp_path / "old.onnx"))
    g = ContactGate()
    g.capture_background([_background()])
    rt = ForceRuntime([Sensor("s", ListSource(_frames(2)), g)], watch, RuntimeOptions(deadline_ms=1e9))
    rt.run()
    assert [k for k, _ in watch.seen] == ["full", "full"] and watch.seen[0][1].shape[1:] == FRAME_SHAPE


def test_gate_reduces_into_a_buffer_allocated_once():
    g = ContactGate()
    g.capture_background([_background()])
    frames = _frames(3)
    ids = {id(g.update(f).reduced) for f in frames}
    assert len(ids) == 1 and g.reduction == FrameReduction(Reduction.AREA_2X_STEPS, 4)
    small = g.reduce(frames[0])
    assert small is g.update(frames[0]).reduced
