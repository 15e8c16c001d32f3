"""Smaller findings, each through the real CLI: --max-frames 0, a bad scene
topic at ``scene show``, a 640x480 --background, a depth bundle run from flags without a
mapping, and number flags that must refuse nan/inf when parsed."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge.bundle.store import write_bundle
from tactile_force.edge.cli import main as cli_main

from benchmarks.robustness import make_dataset
from tests.conftest import mean_manifest, mean_model_bytes


@pytest.fixture
def replay(tmp_path):
    return make_dataset(tmp_path / "replay", n=3)


def test_max_frames_zero_is_refused(replay, tmp_path, capsys):
    out = tmp_path / "r.csv"
    rc = cli_main(["run", "--source", str(replay), "--max-frames", "0", "--out", str(out)])
    assert rc == 2 and "--max-frames" in capsys.readouterr().err
    assert not out.exists()


def test_bad_topic_fails_at_scene_show_naming_the_topic_key(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('[runtime]\nbundle = "default"\n[[sensor]]\nname = "digit"\nsource = "virtual"\n'
                     '[[output]]\nkind = "ros2"\ntopic = "/a//b"\n')
    rc = cli_main(["scene", "show", str(scene)])
    err = capsys.readouterr().err
    assert rc == 2 and "output[0]: topic '/a//b'" in err and "--ros2" not in err, err


def test_vga_background_names_the_file_and_the_expected_size(replay, tmp_path, capsys):
    bg = tmp_path / "bg_vga.png"
    cv2.imwrite(str(bg), np.full((480, 640, 3), 90, np.uint8))
    rc = cli_main(["run", "--source", str(replay), "--background", str(bg), "--max-frames", "2"])
    err = capsys.readouterr().err
    assert rc == 2 and str(bg) in err and "480x640" in err and "320x240" in err, err
    assert "reset()" not in err and "gate frame" not in err


def test_depth_bundle_from_flags_without_mapping_names_the_flag(replay, tmp_path, capsys):
    pytest.importorskip("onnx")
    bundle = tmp_path / "d_bundle"
    write_bundle(bundle, mean_model_bytes(20.0, 0.0, True, 5.0, with_rgb=False), mean_manifest("d", "d_bundle"))
    rc = cli_main(["run", "--source", str(replay), "--bundle", str(bundle), "--max-frames", "2"])
    err = capsys.readouterr().err
    assert rc == 2 and "--depth-mapping" in err, err


@pytest.mark.parametrize("argv, flag", [
    (["compress", "teacher.pth", "--frames", "f", "--out", "o", "--budget-ms", "nan"], "--budget-ms"),
    (["compress", "teacher.pth", "--frames", "f", "--out", "o", "--budget-ms", "inf"], "--budget-ms"),
    (["export", "c.pth", "--out", "o", "--tolerance", "nan"], "--tolerance"),
    (["export", "c.pth", "--out", "o", "--width", "inf"], "--width"),
    (["quantize", "b", "--out", "o", "--percentile", "nan"], "--percentile"),
    (["calibrate-depth", "p", "--ball-radius-mm", "2", "--px-per-mm", "20", "-o", "x.npz", "--holdout", "nan"],
     "--holdout"),
    (["synth", "--out", "o", "--edge-fraction", "nan"], "--edge-fraction"),
])
def test_number_flags_refuse_nan_and_inf_when_parsed(tmp_path, monkeypatch, capsys, argv, flag):
    monkeypatch.chdir(tmp_path)
    rc = cli_main(argv)
    err = capsys.readouterr().err
    assert rc == 2 and f"argument {flag}" in err and "finite" in err, err
    assert not (tmp_path / "o").exists()
