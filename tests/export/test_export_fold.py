"""Folding the BGR flip and the 1/255 into conv1 at export: same forces, smaller graph, honest manifest."""

from __future__ import annotations

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.export import CalibrationData, ExportOptions, ForceNet, ModelSpec, build_model, export_bundle
from tactile_force.export.preprocess import fold_input_scaling, input_convs
from tactile_force.export.zoo import VARIANT_INPUTS


def _frames(aurova, variant):
    data = CalibrationData.from_path(aurova, variant)
    return [torch.from_numpy(np.ascontiguousarray(data.inputs[n])) for n in VARIANT_INPUTS[variant]]


@pytest.mark.parametrize("variant", ["rgbmod", "d", "rgbmod+d"])
def test_folded_forcenet_matches_unfolded_on_real_frames(aurova, variant):
    torch.manual_seed(2)
    model = build_model(variant, 0.25).eval()
    before = {k: v.clone() for k, v in model.state_dict().items()}
    spec = ModelSpec(variant, 0.25, 0.25)
    xs = _frames(aurova, variant)
    with torch.no_grad():
        ref = ForceNet(model, spec).eval()(*xs).double()
        folded = ForceNet(model, spec, folded=True, fold_preprocess=True).eval()
        got = folded(*xs).double()
    assert ref.max() - ref.min() > 1e-4  # different frames, different forces: not a constant
    assert (got - ref).abs().max() <= 1e-4
    # the training model is untouched; the folded copy's conv1 holds the flip and the 1/255
    assert all(torch.equal(before[k], v) for k, v in model.state_dict().items())
    orig, new = input_convs(model), input_convs(folded.model)
    assert set(orig) == set(ForceNet(model, spec).input_names)
    for name in orig:
        expect = orig[name].weight.double() / 255.0
        if name == "rgb":
            expect = expect.flip(1)
        torch.testing.assert_close(new[name].weight.double(), expect, rtol=1e-6, atol=0)


def test_fold_refuses_a_model_whose_inputs_do_not_match_the_variant():
    from tactile_force.edge.errors import TactileForceError

    with pytest.raises(TactileForceError, match="variant 'rgbmod'"):
        fold_input_scaling(build_model("d", 0.25), "rgbmod")


@pytest.fixture(scope="module")
def pair(module_tmp, aurova):
    """The same compact RGBmod exported folded (the default) and unfolded."""
    torch.manual_seed(4)
    model = build_model("rgbmod", 0.25).eval()
    opts = dict(variant="rgbmod", width=0.25, input_scale=0.25, parity_data=aurova)
    folded = export_bundle(model, module_tmp / "fold_on", ExportOptions(**opts))
    plain = export_bundle(model, module_tmp / "fold_off", ExportOptions(**opts, fold_preprocess=False))
    return folded, plain


def _head_ops(path, upto="Conv"):
    ops = []
    for n in onnx.load(str(path)).graph.node:
        ops.append(n.op_type)
        if n.op_type == upto:
            return ops
    raise AssertionError(f"no {upto} in {path}")


def test_folded_graph_is_transpose_cast_conv_and_gives_the_same_forces(pair, aurova):
    folded, plain = pair
    # the graph starts at the network resolution: the frame's 4x4 reduction is outside
    assert _head_ops(folded.onnx_path) == ["Transpose", "Cast", "Conv"]
    assert {"Slice", "Div"} <= set(_head_ops(plain.onnx_path))
    g = onnx.load(str(folded.onnx_path)).graph
    assert g.node[0].input[0] == "rgb"  # the transpose runs on the uint8 input
    data = CalibrationData.from_path(aurova, "rgbmod").for_manifest(folded.manifest)
    run = lambda b: ort.InferenceSession(str(b.onnx_path), providers=["CPUExecutionProvider"]).run(  # noqa: E731
        ["force_n"], {"rgb": data.inputs["rgb"]})[0]
    a, b = run(folded), run(plain)
    assert np.ptp(b) > 1e-4 and np.abs(a - b).max() <= 1e-4
    assert folded.manifest.parity.max_abs_diff_n <= 1e-4 and folded.manifest.parity.frames == 11
    assert folded.manifest.parity.reference == "torch eager, unfolded head"


def test_manifest_says_what_was_folded(pair):
    folded, plain = pair
    m = folded.manifest
    assert m.architecture.preprocess_folded is True and plain.manifest.architecture.preprocess_folded is False
    assert m.preprocessing[:3] == ["frame 320x240 -> 80x60 outside the graph, once per frame: area-2x-steps x4 "
                                   "(edge/gate/reduce.py)", "NHWC -> NCHW (uint8)", "cast uint8 -> float32"]
    assert "BGR -> RGB (rgb input): folded into conv1's weights" in m.preprocessing
    assert "divide by 255: folded into conv1's weights" in m.preprocessing
    assert "divide by 255" in plain.manifest.preprocessing


def test_io_bound_predict_returns_fresh_arrays_that_match_the_session(pair, aurova):
    folded, _ = pair
    data = CalibrationData.from_path(aurova, "rgbmod")
    frames = data.inputs["rgb"]
    sess = ort.InferenceSession(str(folded.onnx_path), providers=["CPUExecutionProvider"])
    ref = sess.run(["force_n"], {"rgb": data.for_manifest(folded.manifest).inputs["rgb"]})[0]  # reduced frames
    m = OnnxForceModel(folded)
    one = m.predict(frames[:1])
    two = m.predict(frames[3:5])
    again = m.predict(frames[7:8])
    assert one.shape == (1,) and two.shape == (2,) and one.dtype == np.float32
    np.testing.assert_allclose(one, ref[:1], atol=1e-5)  # not overwritten by the later calls
    np.testing.assert_allclose(two, ref[3:5], atol=1e-5)
    np.testing.assert_allclose(again, ref[7:8], atol=1e-5)


def test_folded_rgbmod_d_exports_both_branches_with_parity(module_tmp, aurova):
    torch.manual_seed(6)
    b = export_bundle(build_model("rgbmod+d", 0.25).eval(), module_tmp / "fold_rgbd",
                      ExportOptions(variant="rgbmod+d", width=0.25, input_scale=0.25, parity_data=aurova))
    assert b.manifest.parity.max_abs_diff_n <= 1e-4
    g = onnx.load(str(b.onnx_path)).graph
    assert not any(n.op_type in ("Slice", "Div") for n in g.node)
    producers = {o: n for n in g.node for o in n.output}
    first = {}
    for n in g.node:  # each input's path: Transpose -> Cast -> Conv (the graph starts at the network resolution)
        if n.op_type == "Conv" and producers[n.input[0]].op_type == "Cast":
            chain = [producers[n.input[0]]]
            while chain[-1].input[0] in producers:
                chain.append(producers[chain[-1].input[0]])
            first[chain[-1].input[0]] = [c.op_type for c in reversed(chain)]
    assert first == {"rgb": ["Transpose", "Cast"], "depth": ["Transpose", "Cast"]}
    assert not any(n.op_type == "AveragePool" for n in g.node)
