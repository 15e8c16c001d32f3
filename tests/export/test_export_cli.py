"""The export / quantize / bundle subcommands, run through the real console-script dispatcher."""

from __future__ import annotations

import json

import pytest
import torch
from tactile_force.edge.cli import main
from tactile_force.export import ModelSpec, build_model, save_checkpoint


@pytest.fixture(scope="module")
def ours(module_tmp):
    torch.manual_seed(2)
    spec = ModelSpec("rgbmod", width=0.25, input_scale=0.25)
    return save_checkpoint(module_tmp / "ours.pth", build_model("rgbmod", 0.25), spec, {"trained_on": "unit test"})


@pytest.mark.parametrize("cmd", ["export", "quantize", "bundle"])
def test_help_explains_usage(cmd, capsys):
    assert main([cmd, "--help"]) == 0
    out = capsys.readouterr().out
    assert "examples:" in out or "verify PATH" in out
    if cmd == "export":
        assert "--variant" in out and "--parity-data" in out and "uint8 BGR" in out
    if cmd == "quantize":
        assert "int8-static" in out and "--calib" in out and "--keep-float" in out


def test_export_quantize_show_verify(ours, module_tmp, aurova, capsys):
    fp32, int8 = module_tmp / "cli_fp32", module_tmp / "cli_int8"
    assert main(["export", str(ours), "--out", str(fp32), "--parity-data", str(aurova)]) == 0
    out = capsys.readouterr().out
    assert "variant   rgbmod   precision fp32" in out and "width 0.25, input scale 0.25" in out
    assert "on 11 frames" in out
    assert main(["quantize", str(fp32), "--out", str(int8), "--calib", str(aurova)]) == 0
    out = capsys.readouterr().out
    assert "precision int8-static" in out and "error     vs fp32 max" in out and "error     vs labels RE" in out
    assert "(11 frames of" in out
    assert main(["bundle", "show", str(int8)]) == 0
    out = capsys.readouterr().out
    assert "precision int8-static" in out and "verified" in out and "unit test" in out
    assert main(["bundle", "show", str(fp32), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["architecture"]["input_scale"] == 0.25
    assert main(["bundle", "verify", str(int8)]) == 0
    assert "ok:" in capsys.readouterr().out


def test_verify_refuses_a_modified_model(ours, module_tmp, aurova, capsys):
    dest = module_tmp / "cli_tampered"
    assert main(["export", str(ours), "--out", str(dest), "--parity-data", str(aurova)]) == 0
    capsys.readouterr()
    onnx_file = dest / "model.onnx"
    onnx_file.write_bytes(onnx_file.read_bytes()[:-100])
    assert main(["bundle", "verify", str(dest)]) == 1
    assert "does not match the manifest" in capsys.readouterr().err


def test_cli_errors_are_one_clear_line(ours, tmp_path, capsys):
    assert main(["export", str(ours), "--variant", "resnet", "--out", str(tmp_path / "x")]) == 2  # bad input
    err = capsys.readouterr().err
    assert "unknown model variant 'resnet'" in err and "Traceback" not in err
    (tmp_path / "weights.pth").write_text("hello")
    assert main(["export", str(tmp_path / "weights.pth"), "--variant", "d", "--out", str(tmp_path / "x")]) == 2
    assert "not a readable PyTorch checkpoint" in capsys.readouterr().err
    assert not (tmp_path / "x").exists()
