"""OAK backend: fail fast without a device, host-fed queues, NN Archive config."""

import importlib.util
import json
import sys
import tarfile

import numpy as np
import pytest
from tactile_force.edge.bundle.manifest import InputKind, InputSpec, Manifest, ModelOutputSpec
from tactile_force.edge.bundle.store import write_bundle
from tactile_force.edge.errors import AcceleratorUnavailableError, BundleError, FrameError
from tactile_force.firmware_bridge import OakForceModel, OakOptions, build_nn_archive

from .fakes import fake_depthai

try:
    HAS_DEPTHAI = importlib.util.find_spec("depthai") is not None
except ValueError:  # sys.modules["depthai"] is None: blocked
    HAS_DEPTHAI = False


def _bundle(tmp_path, variant="rgbmod", precision="fp32"):
    rgb = InputSpec("rgb", InputKind.RGB, [-1, 320, 240, 3])
    depth = InputSpec("depth", InputKind.DEPTH, [-1, 320, 240, 1], colour_order="GRAY")
    inputs = {"rgbmod": [rgb], "d": [depth], "rgbmod+d": [rgb, depth]}[variant]
    m = Manifest(variant=variant, precision=precision, inputs=inputs, name=f"test-{variant}",
                 output=ModelOutputSpec("force"))
    # The OAK path runs the compiled model of the archive, not this graph; the graph is a real
    # one all the same (every loader refuses a bundle bundle verify refuses)
    from tests.conftest import mean_model_bytes

    graph = mean_model_bytes(20.0, 0.0, variant != "rgbmod", depth_scale=5.0, with_rgb=variant != "d")
    return write_bundle(tmp_path / f"b-{variant.replace('+', '_')}", graph, m)


def _archive(tmp_path, bundle, suffix=".dlc"):
    model = tmp_path / f"model{suffix}"
    model.write_bytes(b"\x01" * 64)
    return build_nn_archive(bundle, model, tmp_path / f"{bundle.name}.tar.xz")


# -- no device: fail fast, never touch the slow device constructor -----------------------------------
def test_no_device_fails_fast_with_fake_depthai(tmp_path, monkeypatch):
    dai = fake_depthai(devices=[])
    monkeypatch.setitem(sys.modules, "depthai", dai)
    b = _bundle(tmp_path)
    with pytest.raises(AcceleratorUnavailableError, match="no OAK device available.*CPU backend"):
        OakForceModel(b, OakOptions(archive=_archive(tmp_path, b).path))
    assert dai.calls == ["getAllAvailableDevices"]  # no Device(), no Pipeline()


@pytest.mark.skipif(not HAS_DEPTHAI, reason="depthai not installed (the 'oak' extra); fake-depthai test covers it")
def test_no_device_fails_fast_with_real_depthai(tmp_path, monkeypatch):
    import depthai

    if depthai.Device.getAllAvailableDevices():
        pytest.skip("an OAK is attached to this host")

    def slow(*a, **k):
        raise AssertionError("the ~11 s device constructor must not be called without a device")

    monkeypatch.setattr(depthai, "Device", type("GuardedDevice", (), {
        "getAllAvailableDevices": staticmethod(depthai.Device.getAllAvailableDevices), "__init__": slow}))
    monkeypatch.setattr(depthai, "Pipeline", slow)
    b = _bundle(tmp_path)
    with pytest.raises(AcceleratorUnavailableError, match="no OAK device available"):
        OakForceModel(b, OakOptions(archive=_archive(tmp_path, b).path))


def test_missing_depthai_is_an_unavailable_accelerator(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "depthai", None)  # import depthai -> ImportError
    b = _bundle(tmp_path)
    with pytest.raises(AcceleratorUnavailableError, match=r"tactile-force\[oak\]"):
        OakForceModel(b, OakOptions(archive=_archive(tmp_path, b).path))


def test_two_input_variant_and_missing_archive_are_refused(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "depthai", fake_depthai(["14442C10D1"]))
    with pytest.raises(AcceleratorUnavailableError, match="rgbmod\\+d.*2 inputs"):
        OakForceModel(_bundle(tmp_path, "rgbmod+d"), OakOptions(archive=tmp_path / "x.tar.xz"))
    with pytest.raises(AcceleratorUnavailableError, match="NN Archive not found"):
        OakForceModel(_bundle(tmp_path), OakOptions(archive=tmp_path / "missing.tar.xz"))


# -- with a (fake) device: host-fed queues -------------------------------------------------------------
def test_predict_feeds_frames_through_the_queues(tmp_path, monkeypatch, aurova_dir):
    from tactile_force.edge.data.dataset import AuthorsDataset

    dai = fake_depthai(["14442C10D1"], model=lambda img: float(img[..., 2].mean()) / 10.0)
    monkeypatch.setitem(sys.modules, "depthai", dai)
    b = _bundle(tmp_path)
    frames = np.stack([s.frame for s in AuthorsDataset(aurova_dir)][:4])
    with OakForceModel(b, OakOptions(archive=_archive(tmp_path, b).path)) as oak:
        forces = oak.predict(frames)
        assert forces.dtype == np.float32 and forces.shape == (4,)
        assert forces == pytest.approx(frames[..., 2].reshape(4, -1).mean(axis=1) / 10.0, rel=1e-6)
        assert oak.device_id == "14442C10D1"
        with pytest.raises(FrameError, match=r"rgb: shape \(4, 240, 320, 3\); expected \(N, 320, 240, 3\)"):
            oak.predict(frames.transpose(0, 2, 1, 3))
        with pytest.raises(FrameError, match="uint8"):
            oak.predict(frames.astype(np.float32))
    assert dai.calls[:5] == ["getAllAvailableDevices", "Device", "Pipeline", "NNArchive", "setNNArchive"]
    assert dai.calls[-2:] == ["stop", "Device.close"]


def test_depth_variant_takes_depth_images(tmp_path, monkeypatch):
    dai = fake_depthai(["14442C10D1"], model=lambda img: float(img.max()))
    monkeypatch.setitem(sys.modules, "depthai", dai)
    b = _bundle(tmp_path, "d")
    depth = np.zeros((2, 320, 240, 1), np.uint8)
    depth[0, 100:120, 50:70] = 200
    with OakForceModel(b, OakOptions(archive=_archive(tmp_path, b).path)) as oak:
        assert oak.needs_depth
        assert oak.predict(None, depth).tolist() == [200.0, 0.0]
        with pytest.raises(FrameError, match="depth: required"):
            oak.predict(np.zeros((2, 320, 240, 3), np.uint8))


def test_the_oak_backend_is_a_force_model_the_runtime_serves(tmp_path, monkeypatch, aurova_dir):
    """Every member the runtime reads is declared on the OAK backend (no probing): it reads full
    frames (reduction none, no force calibration), and a runtime serves its estimates."""
    from tactile_force.edge.checks import expect_members
    from tactile_force.edge.gate.contact_gate import ContactGate
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime import ForceModel, ForceRuntime, RuntimeOptions, Sensor
    from tactile_force.edge.sources import ReplayFolderSource, load_background

    from tests.conftest import shared_data

    dai = fake_depthai(["14442C10D1"], model=lambda img: float(img[..., 2].mean()) / 10.0)
    monkeypatch.setitem(sys.modules, "depthai", dai)
    b = _bundle(tmp_path)
    with OakForceModel(b, OakOptions(archive=_archive(tmp_path, b).path)) as oak:
        assert expect_members(oak, ForceModel, "oak") is oak
        assert oak.calibration is None and oak.reduction.factor == 1 and oak.rgb_shape == (320, 240, 3)
        gate = ContactGate()
        gate.capture_background(load_background(shared_data("digit_backgrounds", "aurova_background_b.png")))
        rt = ForceRuntime([Sensor("left", ReplayFolderSource(aurova_dir), gate)], oak,
                          RuntimeOptions(deadline_ms=1e9), owns_model=False)
        readings: list = []
        rt.run(on_reading=readings.append)
        rt.close()
        assert not oak.closed
        cnn = [r for r in readings if not r.flags & (Flags.NO_CONTACT | Flags.INVALID_INPUT)]
        assert cnn and all(r.raw_force_n == r.raw_force_n for r in cnn)
        frames = {tf.index: tf.frame for tf in ReplayFolderSource(aurova_dir)}
        for r in cnn:
            assert r.raw_force_n == pytest.approx(float(oak.predict_reduced(frames[r.frame_index][None])[0]))


# -- NN Archive ----------------------------------------------------------------------------------------
def test_nn_archive_config_follows_the_manifest(tmp_path):
    b = _bundle(tmp_path)
    info = _archive(tmp_path, b, ".blob")
    assert info.platform == "RVC2"
    with tarfile.open(info.path) as tar:
        assert sorted(tar.getnames()) == ["config.json", "model.blob"]
        cfg = json.load(tar.extractfile("config.json"))
    model = cfg["model"]
    assert model["metadata"] == {"name": "test-rgbmod", "path": "model.blob", "precision": "float16"}
    (inp,) = model["inputs"]
    assert inp["shape"] == [1, 320, 240, 3] and inp["layout"] == "NHWC" and inp["dtype"] == "uint8"
    assert inp["preprocessing"]["dai_type"] == "BGR888i"
    assert inp["preprocessing"]["scale"] == [1.0, 1.0, 1.0]  # x/255 is inside the graph
    assert model["outputs"][0]["name"] == "force"
    from tactile_force.edge.bundle.store import load_bundle
    from tactile_force.edge.scene import shipped_bundles

    depth = _archive(tmp_path, load_bundle(shipped_bundles()["d"]), ".dlc")  # a real int8-static D graph
    assert depth.config["model"]["inputs"][0]["preprocessing"]["dai_type"] == "GRAY8"
    assert depth.config["model"]["metadata"]["precision"] == "int8"


@pytest.mark.parametrize("name, content, words", [
    ("model.onnx", b"x", "compile the ONNX file with the vendor toolchain"),
    ("model.blob", b"", "empty"),
    ("model.xml", b"x", "expected .blob/.superblob"),
])
def test_nn_archive_refuses_uncompiled_or_empty_models(tmp_path, name, content, words):
    (tmp_path / name).write_bytes(content)
    with pytest.raises(BundleError, match=words):
        build_nn_archive(_bundle(tmp_path), tmp_path / name, tmp_path / "a.tar.xz")


@pytest.mark.skipif(not HAS_DEPTHAI, reason="depthai not installed (the 'oak' extra)")
def test_real_depthai_parses_our_archive(tmp_path):
    import depthai as dai

    info = _archive(tmp_path, _bundle(tmp_path), ".dlc")
    archive = dai.NNArchive(str(info.path))
    assert (archive.getInputWidth(), archive.getInputHeight()) == (240, 320)
    assert archive.getModelType() == dai.ModelType.DLC
    cfg = archive.getConfigV1()
    assert cfg.model.inputs[0].name == "rgb" and cfg.model.outputs[0].name == "force"
