"""The typed manifest: one reader that names the field, format 1 migration, confinement."""

from __future__ import annotations

import copy
import json
import math
import shutil
import subprocess
import sys

import pytest
from tactile_force.edge import BundleError, load_bundle, read_manifest
from tactile_force.edge.bundle.manifest import (
    FORMAT_VERSION,
    InputKind,
    Manifest,
    Precision,
    Variant,
    manifest_from_json,
)
from tactile_force.edge.scene import default_bundle_path
from tactile_force.edge.typed_json import to_json

FORMAT_1 = {
    "variant": "rgbmod", "precision": "int8-static", "format_version": 1, "name": "old", "sha256": "ab",
    "onnx_file": "model.onnx",
    "inputs": [{"name": "rgb", "shape": [-1, 320, 240, 3], "dtype": "uint8", "kind": "rgb", "layout": "NHWC",
                "colour_order": "BGR", "scaling": "x / 255 inside the graph", "unit": ""}],
    "output": {"name": "force_n", "shape": [-1], "dtype": "float32", "kind": "force", "layout": "N",
               "colour_order": "", "scaling": "", "unit": "N"},
    "preprocessing_in_graph": ["cast uint8 -> float32"],
    "architecture": {"family": "resnet18", "width": 0.25, "input_scale": 0.25, "network_input_hw": [80, 60],
                     "gmacs": 0.014, "depth": {"mapping": "package:virtual_digit_depth.npz", "mode": "exact",
                                               "levels_per_px": 2.0}},
    "quantization": {"format": "QDQ", "method": "minmax", "kept_float": ["node_linear"], "calibration_frames": 200},
    "parity": {"max_abs_diff_n": 5e-6, "frames": 32, "data": "synthetic"},
    "error": {"data": "synthetic test", "frames": 424, "same_frames_as_calibration": False,
              "vs_fp32": {"max_abs_diff_n": 0.28, "mean_abs_diff_n": 0.05, "n": 424, "re_mean": 0.009,
                          "re_std": 0.01, "mae_mean": 0.05, "mae_std": 0.04, "n_excluded_re": 0},
              "vs_ground_truth": {"quantized": {"n": 424, "re_mean": 0.078, "re_std": 0.05, "mae_mean": 0.65,
                                                "mae_std": 0.61},
                                  "fp32": {"n": 424, "re_mean": 0.077, "re_std": 0.05, "mae_mean": 0.66,
                                           "mae_std": 0.61}}},
    "provenance": {"checkpoint": "model.pth", "trained_on": "synthetic", "quantized_from": {"bundle": "a", "sha256": "b"},
                   "custom_key": "kept"},
}


def test_format_1_is_migrated_into_typed_sections():
    m = manifest_from_json(copy.deepcopy(FORMAT_1))
    assert m.format_version == FORMAT_VERSION and m.variant is Variant.RGBMOD and m.precision is Precision.INT8_STATIC
    assert m.error.vs_truth.re_mean == 0.078 and m.error.fp32_vs_truth.re_mean == 0.077  # was vs_ground_truth
    assert m.error_score() == 0.078  # the ladder's key: what quantize_bundle measured, never inf
    assert m.depth is None  # format 1 kept a depth record in every architecture; an RGBmod graph reads none
    assert m.architecture.width == 0.25 and m.quantization.kept_float == ["node_linear"]
    assert m.provenance.quantized_from.bundle == "a" and m.provenance.extra == {"custom_key": "kept"}
    assert m.inputs[0].kind is InputKind.RGB and m.preprocessing == ["cast uint8 -> float32"]
    again = manifest_from_json(json.loads(m.to_json()))  # format 2 round trip
    assert to_json(again) == to_json(m)
    d = copy.deepcopy(FORMAT_1)  # a depth variant keeps its record
    d["variant"] = "rgbmod+d"
    d["inputs"].append({"name": "depth", "kind": "depth", "shape": [-1, 320, 240, 1], "dtype": "uint8",
                        "layout": "NHWC", "colour_order": "GRAY"})
    md = manifest_from_json(d)
    assert md.depth.mapping == "package:virtual_digit_depth.npz" and md.depth.levels_per_px == 2.0


def test_shipped_default_bundle_is_format_2_with_a_real_score():
    b = load_bundle(default_bundle_path())
    assert b.manifest.format_version == FORMAT_VERSION
    assert math.isfinite(b.manifest.error_score())


@pytest.mark.parametrize("path, value, message", [
    (("error", "vs_ground_truth", "quantized", "re_mean"), "abc", "error.vs_truth.re_mean: expected a number"),
    (("architecture", "width"), "abc", "architecture.width: expected a number"),
    (("parity", "frames"), 3.5, "parity.frames: expected an integer"),
    (("variant",), "resnet", "variant: expected one of 'rgbmod', 'd', 'dmod', 'rgbmod\\+d', got 'resnet'"),
    (("inputs",), {"name": "rgb"}, "inputs: expected a list"),
    (("precision",), None, "precision: expected one of 'fp32', 'fp16', 'int8-static', 'int8-dynamic', got None"),
    (("onnx_file",), "../../x/model.onnx", "onnx_file '../../x/model.onnx': expected a plain file name"),
    (("onnx_file",), "/etc/model.onnx", "expected a plain file name"),
])
def test_a_bad_field_is_named(path, value, message):
    raw = copy.deepcopy(FORMAT_1)
    node = raw
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    with pytest.raises(BundleError, match=message.replace("(", r"\(").replace(".", r"\.")):
        manifest_from_json(raw, source="m.json")


def test_variant_must_match_the_inputs():
    raw = copy.deepcopy(FORMAT_1)
    raw["variant"] = "d"
    with pytest.raises(BundleError, match=r"variant 'd' needs inputs of kind \['depth'\]"):
        manifest_from_json(raw)


def test_unknown_fields_and_versions_are_refused():
    raw = json.loads(manifest_from_json(copy.deepcopy(FORMAT_1)).to_json())
    raw["parity"]["surprise"] = 1
    with pytest.raises(BundleError, match="parity: unknown key 'surprise'; allowed keys: max_abs_diff_n, frames"):
        manifest_from_json(raw)
    raw = copy.deepcopy(FORMAT_1)
    raw["format_version"] = 9
    with pytest.raises(BundleError, match="format_version 9"):
        manifest_from_json(raw)
    with pytest.raises(BundleError, match="not a tactile-force manifest"):
        manifest_from_json([1, 2])


@pytest.mark.parametrize("content", [b"\xff\xfe\x00garbage", b'{"variant": "rgbmod", "precis', b""])
def test_damaged_manifest_files_name_the_file(tmp_path, content):
    p = tmp_path / "model.json"
    p.write_bytes(content)
    with pytest.raises(BundleError, match="model.json"):
        read_manifest(p)


def test_onnx_file_outside_the_bundle_is_never_followed(tmp_path):
    dest = tmp_path / "b"
    shutil.copytree(default_bundle_path(), dest)
    outside = tmp_path / "x"
    outside.mkdir()
    shutil.copy(dest / "model.onnx", outside / "model.onnx")
    raw = json.loads((dest / "model.json").read_text())
    raw["onnx_file"] = "../x/model.onnx"
    (dest / "model.json").write_text(json.dumps(raw))
    with pytest.raises(BundleError, match="plain file name"):
        load_bundle(dest)


def test_bundle_verify_refuses_a_variant_the_graph_does_not_have(tmp_path):
    dest = tmp_path / "b"
    shutil.copytree(default_bundle_path(), dest)
    raw = json.loads((dest / "model.json").read_text())
    raw["variant"] = "d"
    raw["inputs"][0].update(kind="depth", shape=[-1, 320, 240, 1], colour_order="GRAY")
    (dest / "model.json").write_text(json.dumps(raw))
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "bundle", "verify", str(dest)],
                         capture_output=True, text=True)
    assert run.returncode == 1, run.stderr
    assert "Traceback" not in run.stderr and "FAILED" in run.stderr and "uint8" not in run.stdout
    assert "shape" in run.stderr  # the graph's rgb input is 3-channel: it does not fit a depth contract


def test_bundle_verify_and_show_on_the_default_bundle():
    for action in ("verify", "show"):
        run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "bundle", action,
                              str(default_bundle_path())], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
    assert "error     vs labels RE" in run.stdout


def test_manifest_constructor_takes_plain_strings():
    m = Manifest(variant="rgbmod+d", precision="fp32", inputs=[])
    assert m.variant is Variant.RGBMOD_D and m.needs_depth and f"{m.variant}" == "rgbmod+d"
