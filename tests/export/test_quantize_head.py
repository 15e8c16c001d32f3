"""int8 keeps the head honest: the pooled features and their concatenation stay float."""

from __future__ import annotations

import numpy as np
import onnx
import onnxruntime as ort
import pytest
import torch
from tactile_force.export import (
    CalibrationData,
    ExportOptions,
    QuantizeOptions,
    build_model,
    export_bundle,
    quantize_bundle,
)
from tactile_force.export.quantize import head_input_nodes


@pytest.fixture(scope="module")
def fp32(module_tmp, aurova):
    torch.manual_seed(5)
    model = build_model("rgbmod", 0.25).eval()
    with torch.no_grad():
        model.fc4.bias.fill_(5.0)  # forces around 5 N, so RE against fp32 is defined
    return export_bundle(model, module_tmp / "head_fp32",
                         ExportOptions(variant="rgbmod", width=0.25, input_scale=0.25, parity_data=aurova))


def _head_inputs_quantized(path) -> bool:
    m = onnx.load(str(path))
    producers = {o: n for n in m.graph.node for o in n.output}
    concat = next(n for n in m.graph.node if n.op_type == "Concat")
    feeders = [producers[i] for i in concat.input if i in producers]
    return any(f.op_type == "DequantizeLinear" for f in feeders) or any(
        n.op_type == "DequantizeLinear" and concat.output[0] in n.input for n in m.graph.node)


def test_head_input_nodes_are_the_pooling_and_the_concat(fp32):
    m = onnx.load(str(fp32.onnx_path))
    gemm = next(n for n in m.graph.node if n.op_type == "Gemm")
    ops = sorted(n.op_type for n in m.graph.node if n.name in head_input_nodes(m, gemm.name))
    assert ops.count("Concat") == 1 and ops.count("ReduceMean") == 3
    assert not {"Conv", "Relu", "Add"} & set(ops)


def test_float_head_is_the_default_and_is_closer_to_fp32(fp32, module_tmp, aurova):
    calib = CalibrationData.from_path(aurova, "rgbmod")
    kept = quantize_bundle(fp32, module_tmp / "head_float", QuantizeOptions(overwrite=True), calibration=calib)
    quant = quantize_bundle(fp32, module_tmp / "head_int8", QuantizeOptions(float_head_inputs=False, overwrite=True),
                            calibration=calib)
    assert not _head_inputs_quantized(kept.onnx_path)
    assert _head_inputs_quantized(quant.onnx_path)
    extra = set(kept.manifest.quantization.kept_float) - set(quant.manifest.quantization.kept_float)
    assert len(extra) == 4  # three poolings and the concat
    x = {"rgb": calib.for_manifest(fp32.manifest).inputs["rgb"]}  # the graph reads the reduced 80x60 frames
    ref = ort.InferenceSession(str(fp32.onnx_path)).run(["force_n"], x)[0]
    a = ort.InferenceSession(str(kept.onnx_path)).run(["force_n"], x)[0]
    b = ort.InferenceSession(str(quant.onnx_path)).run(["force_n"], x)[0]
    assert np.all(np.isfinite(a)) and np.all(np.isfinite(b))
    assert np.abs(a - ref).max() <= np.abs(b - ref).max() + 1e-6
