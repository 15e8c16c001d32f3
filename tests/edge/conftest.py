"""Test bundles: small real ONNX graphs that honour the bundle contract, written with
edge.bundle.write_bundle and run by real ONNX Runtime sessions.

The 'mean model' predicts force_n = scale * mean(rgb) / 255 + bias (one value per frame,
output (N, 1) float32 like a CNN head), so expected forces are easy to compute in tests.
The depth variant adds depth_scale * mean(depth) / 255.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from tactile_force.edge.bundle.manifest import ErrorReport, InputKind, InputSpec, Manifest, ModelOutputSpec, Provenance
from tactile_force.edge.bundle.store import write_bundle


def mean_model_bytes(scale: float, bias: float, with_depth: bool, depth_scale: float = 0.0,
                     with_rgb: bool = True) -> bytes:
    """A tiny real ONNX graph: force = bias + scale * mean(rgb)/255 [+ depth_scale * mean(depth)/255]."""
    onnx = pytest.importorskip("onnx", reason="building test bundles needs the 'onnx' package (dev extra)")
    from onnx import TensorProto, helper

    nodes = [
        helper.make_node("Cast", ["rgb"], ["rgb_f"], to=TensorProto.FLOAT),
        helper.make_node("ReduceMean", ["rgb_f"], ["m"], axes=[1, 2, 3], keepdims=0),
        helper.make_node("Mul", ["m", "k"], ["mk"]),
        helper.make_node("Add", ["mk", "b"], ["f"]),
    ]
    inits = [helper.make_tensor("k", TensorProto.FLOAT, [], [scale / 255.0]),
             helper.make_tensor("b", TensorProto.FLOAT, [], [bias]),
             helper.make_tensor("shape", TensorProto.INT64, [2], [-1, 1])]
    inputs = [helper.make_tensor_value_info("rgb", TensorProto.UINT8, ["N", 320, 240, 3])]
    last = "f"
    if not with_rgb:  # D / Dmod graphs read only the depth image
        nodes = [helper.make_node("Constant", [], ["f"], value=helper.make_tensor("f0", TensorProto.FLOAT, [], [bias]))]
        inputs = []
    if with_depth:
        inputs.append(helper.make_tensor_value_info("depth", TensorProto.UINT8, ["N", 320, 240, 1]))
        nodes += [helper.make_node("Cast", ["depth"], ["d_f"], to=TensorProto.FLOAT),
                  helper.make_node("ReduceMean", ["d_f"], ["dm"], axes=[1, 2, 3], keepdims=0),
                  helper.make_node("Mul", ["dm", "kd"], ["dmk"]),
                  helper.make_node("Add", ["f", "dmk"], ["fd"])]
        inits.append(helper.make_tensor("kd", TensorProto.FLOAT, [], [depth_scale / 255.0]))
        last = "fd"
    nodes.append(helper.make_node("Reshape", [last, "shape"], ["force"]))
    graph = helper.make_graph(nodes, "mean_force", inputs,
                              [helper.make_tensor_value_info("force", TensorProto.FLOAT, ["N", 1])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    return model.SerializeToString()


def mean_manifest(variant: str, name: str, error: ErrorReport | None = None) -> Manifest:
    inputs = [InputSpec("rgb", InputKind.RGB, [-1, 320, 240, 3])] if variant in ("rgbmod", "rgbmod+d") else []
    if variant != "rgbmod":
        inputs.append(InputSpec("depth", InputKind.DEPTH, [-1, 320, 240, 1], colour_order="GRAY"))
    return Manifest(variant=variant, precision="fp32", inputs=inputs, output=ModelOutputSpec("force", [-1, 1]),
                    name=name, error=error, provenance=Provenance(note="test mean model, not trained"))


@pytest.fixture(scope="session")
def make_bundle(tmp_path_factory):
    """make_bundle(name, variant='rgbmod', scale=20.0, bias=0.0, error=None) -> bundle folder."""
    root = tmp_path_factory.mktemp("bundles")

    def make(name: str, variant: str = "rgbmod", scale: float = 20.0, bias: float = 0.0,
             error: ErrorReport | None = None) -> Path:
        dest = root / name
        if not dest.exists():
            data = mean_model_bytes(scale, bias, variant != "rgbmod", depth_scale=5.0,
                                    with_rgb=variant in ("rgbmod", "rgbmod+d"))
            write_bundle(dest, data, mean_manifest(variant, name, error))
        return dest

    return make


@pytest.fixture(scope="session")
def rgb_bundle(make_bundle) -> Path:
    return make_bundle("mean_rgbmod")
