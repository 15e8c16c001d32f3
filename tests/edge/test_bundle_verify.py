"""``bundle verify`` checks what the graph really holds (issue 19, Build 5): the manifest's
precision against the graph's op types and weight types (without the ``onnx`` package, as on
the robot), and refuses files that resolve outside the bundle (symbolic links)."""

from __future__ import annotations

import os
import shutil
import sys

from tactile_force.edge.bundle import load_bundle, write_bundle
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.scene import default_bundle_path


def _relabel(src, dest, precision: str):
    """The same graph written as a new bundle whose manifest claims ``precision``."""
    b = load_bundle(src)
    m = b.manifest
    m.precision = type(m.precision)(precision)
    if precision == "fp32":
        m.quantization = None
    return write_bundle(dest, b.onnx_path.read_bytes(), m).path


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
    rc, out = _verify(default_bundle_path(), capsys)
    assert rc == 0, out
    rc, out = _verify(_relabel(default_bundle_path(), tmp_path / "claims-fp32", "fp32"), capsys)
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
