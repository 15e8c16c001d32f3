"""``bundle verify`` checks what the graph really holds: the manifest's
precision against the graph's op types and weight types (without the ``onnx`` package, as on
the robot), and refuses files that resolve outside the bundle (symbolic links)."""

from __future__ import annotations

import os
import shutil
import sys

from tactile_force.edge.bundle.store import load_bundle
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.scene import default_bundle_path, shipped_bundles


def _relabel(src, dest, precision: str):
    """A copy of bundle ``src`` whose model.json claims ``precision`` (write_bundle refuses to
    write such a bundle: the manifest is edited on disk, as a user or a broken tool would)."""
    def edit(m):
        m["precision"] = precision
        if precision == "fp32":
            m["quantization"] = None
    return _edited(src, dest, edit)


def _verify(path, capsys) -> tuple[int, str]:
    rc = cli_main(["bundle", "verify", str(path)])
    cap = capsys.readouterr()
    return rc, cap.out + cap.err


def _no_onnx(monkeypatch) -> None:
    """The robot side from here on: the 'onnx' package cannot be imported."""
    monkeypatch.setitem(sys.modules, "onnx", None)


def test_an_fp32_graph_whose_manifest_says_int8_static_fails_verify(make_bundle, tmp_path, capsys, monkeypatch):
    fp32 = make_bundle("verify-fp32")
    _no_onnx(monkeypatch)
    rc, out = _verify(fp32, capsys)
    assert rc == 0 and "ok:" in out
    lie = _relabel(fp32, tmp_path / "claims-int8", "int8-static")
    rc, out = _verify(lie, capsys)
    assert rc == 1 and "int8-static" in out and "QuantizeLinear" in out and "Traceback" not in out
    rc, out = _verify(_relabel(fp32, tmp_path / "claims-fp16", "fp16"), capsys)
    assert rc == 1 and "float16" in out


def test_a_real_int8_graph_passes_and_fails_when_it_claims_fp32(tmp_path, capsys, monkeypatch):
    _no_onnx(monkeypatch)
    rc, out = _verify(shipped_bundles()["rgbmod_int8"], capsys)
    assert rc == 0, out
    rc, out = _verify(_relabel(shipped_bundles()["rgbmod_int8"], tmp_path / "claims-fp32", "fp32"), capsys)
    assert rc == 1 and "fp32" in out and "DequantizeLinear" in out


def test_a_model_file_linked_from_outside_the_bundle_is_refused(make_bundle, tmp_path, capsys):
    src = make_bundle("verify-link")
    outside = tmp_path / "elsewhere" / "model.onnx"
    outside.parent.mkdir()
    shutil.copy(src / "model.onnx", outside)
    linked = tmp_path / "linked"
    linked.mkdir()
    shutil.copy(src / "model.json", linked / "model.json")
    os.symlink(outside, linked / "model.onnx")
    rc, out = _verify(linked, capsys)
    assert rc == 1 and "outside the bundle" in out and "model.onnx" in out


def _edited(src, dest, edit):
    """A copy of bundle ``src`` whose model.json is changed by ``edit(dict)`` (the ONNX file and
    its recorded sha256 unchanged: only the manifest's claims differ)."""
    import json

    shutil.copytree(src, dest)
    raw = json.loads((dest / "model.json").read_text())
    edit(raw)
    (dest / "model.json").write_text(json.dumps(raw, indent=2))
    return dest


def test_a_static_int8_graph_whose_manifest_says_int8_dynamic_fails_verify(tmp_path, capsys, monkeypatch):
    _no_onnx(monkeypatch)
    int8 = shipped_bundles()["rgbmod_int8"]
    lie = _edited(int8, tmp_path / "claims-dynamic", lambda m: m.update(precision="int8-dynamic"))
    rc, out = _verify(lie, capsys)
    assert rc == 1 and "int8-dynamic" in out and "int8-static" in out and "QuantizeLinear" in out, out
    assert "Traceback" not in out


def test_a_manifest_input_scale_contradicting_the_graph_input_fails_verify(tmp_path, capsys, monkeypatch):
    """The shipped default graph reads 80 x 60 images (input scale 0.25)."""
    _no_onnx(monkeypatch)
    half = _edited(default_bundle_path(), tmp_path / "scale-half",
                   lambda m: m["architecture"].update(input_scale=0.5))
    rc, out = _verify(half, capsys)
    assert rc == 1 and "input_scale 0.5" in out and "160 x 120" in out and "80 x 60" in out, out
    both = _edited(default_bundle_path(), tmp_path / "scale-and-hw",
                   lambda m: m["architecture"].update(input_scale=0.5, network_input_hw=[160, 120]))
    rc, out = _verify(both, capsys)
    assert rc == 1 and "graph input 'rgb' is 80 x 60" in out, out
    hw = _edited(default_bundle_path(), tmp_path / "hw",
                 lambda m: m["architecture"].update(network_input_hw=[320, 240]))
    rc, out = _verify(hw, capsys)
    assert rc == 1 and "network_input_hw [320, 240]" in out, out


def test_the_precision_verify_finds_on_every_kind_of_graph(make_bundle, tmp_path):
    """One reading of the graph (graph_facts.graph_precision) for verify and bench: the shipped
    int8-static graphs and the fp32 default, an fp32 graph, its fp16 conversion and its dynamic int8 quantization."""
    import onnx
    from onnx import TensorProto, helper
    from onnxruntime.quantization import QuantType, quantize_dynamic
    from onnxruntime.transformers.float16 import convert_float_to_float16
    from tactile_force.edge.bundle.graph_facts import graph_facts, graph_precision, manifest_problems
    from tactile_force.edge.scene import shipped_bundles

    shipped = {"default": "fp32", "d": "int8-static", "rgbmod_d": "int8-static", "rgbmod_int8": "int8-static"}
    for name, path in shipped_bundles().items():
        b = load_bundle(path)
        facts = graph_facts(b.onnx_path)
        assert graph_precision(facts) == shipped[name] and manifest_problems(b.manifest, facts) == [], path
    fp32 = load_bundle(make_bundle("verify-kinds"))
    assert graph_precision(graph_facts(fp32.onnx_path)) == "fp32"
    model = onnx.load(str(fp32.onnx_path))
    f16 = tmp_path / "f16.onnx"
    onnx.save(convert_float_to_float16(model, keep_io_types=True), str(f16))
    assert graph_precision(graph_facts(f16)) == "fp16"
    # a graph with a weight matrix (what dynamic quantization turns into MatMulInteger)
    g = helper.make_graph(
        [helper.make_node("MatMul", ["x", "w"], ["y"])], "mm",
        [helper.make_tensor_value_info("x", TensorProto.FLOAT, ["N", 64])],
        [helper.make_tensor_value_info("y", TensorProto.FLOAT, ["N", 64])],
        [helper.make_tensor("w", TensorProto.FLOAT, [64, 64], [0.01 * (i % 7) for i in range(64 * 64)])])
    mm = helper.make_model(g, opset_imports=[helper.make_opsetid("", 17)])
    mm.ir_version = 8
    src, dyn = tmp_path / "mm.onnx", tmp_path / "mm_dyn.onnx"
    onnx.save(mm, str(src))
    quantize_dynamic(str(src), str(dyn), weight_type=QuantType.QInt8)
    facts = graph_facts(dyn)
    assert {"DynamicQuantizeLinear", "MatMulInteger"} <= set(facts.ops) and graph_precision(facts) == "int8-dynamic"
    assert graph_precision(graph_facts(src)) == "fp32" and list(facts.inputs) == ["x"]


def test_a_manifest_whose_blocks_or_width_contradict_the_graph_fails_verify_and_every_loader(tmp_path, capsys,
                                                                                               monkeypatch):
    """The default bundle's graph (the fast RGBmod) is one residual block per stage at width 1/8 (12 convolutions, a stem of
    8 channels); a manifest claiming ResNet-18's blocks, one more block, or another width is refused by
    verify and by load_bundle (every loader), naming the field and what the graph holds."""
    import pytest
    from tactile_force.edge.errors import BundleError
    from tactile_force.edge.scene import shipped_bundles

    _no_onnx(monkeypatch)
    fast = shipped_bundles()["default"]
    rc, out = _verify(fast, capsys)
    assert rc == 0, out
    for i, (arch, said) in enumerate((({"blocks": [2, 2, 2, 2]}, "architecture.blocks [2, 2, 2, 2]"),
                                      ({"blocks": [1, 1, 1, 2]}, "has 12 in 1 trunk"),
                                      ({"width": 0.5}, "architecture.width 0.5"))):
        lie = _edited(fast, tmp_path / f"lie{i}", lambda m, a=arch: m["architecture"].update(a))
        rc, out = _verify(lie, capsys)
        assert rc == 1 and said in out and "Traceback" not in out, out
        with pytest.raises(BundleError, match=said.split(" ")[0]):
            load_bundle(lie)
