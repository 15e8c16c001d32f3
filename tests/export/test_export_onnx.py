"""ONNX export of the authors' checkpoints: parity on real frames, manifest, bundle integrity."""

from __future__ import annotations

import cv2
import numpy as np
import onnxruntime as ort
import pytest
import torch
from tactile_force.edge.bundle.store import load_bundle
from tactile_force.edge.errors import BundleError
from tactile_force.export import (
    CalibrationData,
    ExportOptions,
    ForceNet,
    ModelSpec,
    ParityError,
    build_model,
    count_macs,
    export_bundle,
    model_from_checkpoint,
)

from tests.export.authors_format import save_authors_checkpoint


def _no_partial(parent, name):
    return not (parent / name).exists() and not list(parent.glob(f".{name}.*"))


@pytest.fixture(scope="module")
def rgbmod_full(module_tmp, aurova):
    """The authors' RGBmod at full resolution and width, exported with parity on the real frames."""
    ckpt = save_authors_checkpoint(module_tmp / "rgbmod.pth.tar", "rgbmod", seed=3)
    bundle = export_bundle(ckpt, module_tmp / "rgbmod_fp32", ExportOptions(variant="rgbmod", parity_data=aurova))
    return ckpt, bundle


def test_authors_rgbmod_full_resolution_exports_with_parity(rgbmod_full, aurova):
    ckpt, b = rgbmod_full
    m = b.manifest
    assert m.parity.frames == 11 and "aurova_digit_grasp" in m.parity.data
    assert m.parity.max_abs_diff_n <= 1e-4
    # independent re-check: our own ORT session vs torch eager on every real frame, one at a time
    model, spec, _ = model_from_checkpoint(ckpt, variant="rgbmod")
    net = ForceNet(model, spec).eval()
    sess = ort.InferenceSession(str(b.onnx_path), providers=["CPUExecutionProvider"])
    data = CalibrationData.from_path(aurova, "rgbmod")
    got = sess.run(["force_n"], {"rgb": data.inputs["rgb"]})[0]
    with torch.no_grad():
        ref = net(torch.from_numpy(data.inputs["rgb"])).numpy()
    assert got.dtype == np.float32 and got.shape == (11,)
    assert np.abs(got - ref).max() <= 1e-4
    assert np.ptp(ref) > 1e-3  # the frames give different forces: parity is not checked on a constant


def test_manifest_describes_inputs_graph_and_provenance(rgbmod_full):
    ckpt, b = rgbmod_full
    m = load_bundle(b.path).manifest
    assert m.variant == "rgbmod" and m.precision == "fp32"
    (inp,) = m.inputs
    assert (inp.name, inp.shape, inp.dtype, inp.layout, inp.colour_order) == ("rgb", [-1, 320, 240, 3], "uint8",
                                                                              "NHWC", "BGR")
    assert (m.output.name, m.output.dtype, m.output.unit) == ("force_n", "float32", "N")
    assert "BGR -> RGB (rgb input): folded into conv1's weights" in m.preprocessing
    assert "divide by 255: folded into conv1's weights" in m.preprocessing
    assert m.architecture.head_folded and m.architecture.preprocess_folded and m.architecture.network_input_hw == [320, 240]
    assert 2.5 < m.architecture.gmacs < 3.2  # ResNet-18 at 320x240 ~ 1.82 GMACs * (320*240)/(224*224)
    import hashlib

    assert m.provenance.checkpoint_sha256 == hashlib.sha256(ckpt.read_bytes()).hexdigest()
    assert m.provenance.checkpoint_format.startswith("authors'")


def test_graph_batch_is_dynamic_and_takes_raw_bgr_frames(rgbmod_full, aurova):
    _, b = rgbmod_full
    sess = ort.InferenceSession(str(b.onnx_path), providers=["CPUExecutionProvider"])
    (inp,) = sess.get_inputs()
    assert inp.type == "tensor(uint8)" and inp.shape[1:] == [320, 240, 3]
    frames = np.stack([cv2.imread(str(aurova / "images" / f"{n}.png")) for n in (1500, 1510, 1524)])
    batched = sess.run(None, {"rgb": frames})[0]
    single = np.array([sess.run(None, {"rgb": f[None]})[0][0] for f in frames])
    np.testing.assert_allclose(batched, single, atol=1e-5)
    swapped = sess.run(None, {"rgb": np.ascontiguousarray(frames[..., ::-1])})[0]
    assert np.abs(swapped - batched).max() > 1e-4  # the graph does care about colour order


@pytest.mark.parametrize("variant", ["d", "rgbmod+d"])
def test_authors_depth_checkpoints_export_with_parity_on_real_depth_images(module_tmp, aurova, variant):
    ckpt = save_authors_checkpoint(module_tmp / f"{variant}.pth", variant, seed=5, wrap=variant == "d")
    # full width (the authors' exact shapes); a 1/4 input scale keeps this test quick on small CPUs
    b = export_bundle(ckpt, module_tmp / f"{variant}_fp32",
                      ExportOptions(variant=variant, input_scale=0.25, parity_data=aurova))
    m = b.manifest
    assert m.parity.max_abs_diff_n <= 1e-4 and m.parity.frames == 11
    assert [s.name for s in m.inputs] == (["depth"] if variant == "d" else ["rgb", "depth"])
    # a 1/4 input scale: the graph starts at the network resolution
    assert m.inputs[-1].shape == [-1, 80, 60, 1] and m.inputs[-1].colour_order == "GRAY"
    assert m.inputs[-1].reduction.factor == 4
    assert m.needs_depth


def test_count_macs_matches_torch_conv_and_linear_hooks():
    torch.manual_seed(0)
    spec = ModelSpec("rgbmod", 0.25, 0.5)
    net = ForceNet(build_model("rgbmod", 0.25).eval(), spec, folded=True).eval()
    hooked = []

    def hook(mod, inp, out):
        if isinstance(mod, torch.nn.Conv2d):
            hooked.append(out.numel() * mod.in_channels // mod.groups * mod.kernel_size[0] * mod.kernel_size[1])
        else:
            hooked.append(out.numel() * mod.in_features)

    handles = [mod.register_forward_hook(hook) for mod in net.modules()
               if isinstance(mod, torch.nn.Conv2d) or mod is net.head]
    with torch.no_grad():
        net(torch.zeros(1, 320, 240, 3, dtype=torch.uint8))
    for h in handles:
        h.remove()
    import onnx
    from tactile_force.export.onnx_export import to_onnx

    macs = count_macs(onnx.load_from_string(to_onnx(net)))
    assert macs.total == sum(hooked)
    assert macs.by_op["Gemm"] == net.head.in_features


def test_parity_failure_leaves_no_bundle(module_tmp, aurova):
    torch.manual_seed(7)
    model = build_model("d", 0.25)
    with pytest.raises(ParityError, match="No bundle written"):
        export_bundle(model, module_tmp / "never", ExportOptions(variant="d", width=0.25, input_scale=0.25,
                                                                 parity_data=aurova, parity_tol_n=1e-12))
    assert _no_partial(module_tmp, "never")


def test_bad_checkpoint_leaves_no_bundle(tmp_path):
    (tmp_path / "notes.pth").write_text("not weights")
    from tactile_force.export import CheckpointError

    with pytest.raises(CheckpointError):
        export_bundle(tmp_path / "notes.pth", tmp_path / "out", ExportOptions(variant="rgbmod"))
    assert _no_partial(tmp_path, "out")


def test_tampered_or_truncated_bundle_is_refused(rgbmod_full, tmp_path):
    import shutil

    _, b = rgbmod_full
    for case in ("flipped", "truncated"):
        copy = tmp_path / case
        shutil.copytree(b.path, copy)
        data = bytearray((copy / "model.onnx").read_bytes())
        if case == "flipped":
            data[len(data) // 2] ^= 0xFF
        else:
            data = data[: len(data) // 3]
        (copy / "model.onnx").write_bytes(bytes(data))
        with pytest.raises(BundleError, match="does not match the manifest"):
            load_bundle(copy)
