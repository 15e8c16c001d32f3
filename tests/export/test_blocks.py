"""Residual blocks per stage: a model parameter carried by checkpoints, manifests and compress's ladder."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch
from tactile_force.edge import load_bundle
from tactile_force.edge.bundle.manifest import Architecture
from tactile_force.edge.errors import TactileForceError
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.scene import default_bundle_path
from tactile_force.edge.typed_json import TypedJsonError, from_json
from tactile_force.export import (
    CheckpointError,
    ExportOptions,
    ForceNet,
    ModelSpec,
    build_model,
    export_bundle,
    model_from_checkpoint,
    save_checkpoint,
)
from tactile_force.export.compress import CompressError, Rung, error_steps, parse_ladder

ONE = (1, 1, 1, 1)


@pytest.mark.parametrize("variant", ["rgbmod", "d", "dmod", "rgbmod+d"])
def test_fewer_blocks_keep_torchvision_keys_and_the_folded_head(variant):
    torch.manual_seed(0)
    model = build_model(variant, 0.25, ONE).eval()
    keys = set(model.state_dict())
    prefix = {"rgbmod+d": "model_rgb."}.get(variant, "")
    assert f"{prefix}layer1.0.conv1.weight" in keys and f"{prefix}layer4.0.downsample.0.weight" in keys
    assert not any(".1.conv1" in k for k in keys)  # no second block in any stage
    full = build_model(variant, 0.25)
    assert sum(p.numel() for p in model.parameters()) < 0.7 * sum(p.numel() for p in full.parameters())
    spec = ModelSpec(variant, 0.25, 0.25, ONE)
    frames = {"rgb": torch.randint(0, 256, (2, 320, 240, 3), dtype=torch.uint8),
              "depth": torch.randint(0, 256, (2, 320, 240, 1), dtype=torch.uint8)}
    a, b = ForceNet(model, spec), ForceNet(model, spec, folded=True)
    args = [frames[n] for n in a.input_names]
    with torch.no_grad():
        torch.testing.assert_close(b(*args), a(*args), atol=1e-5, rtol=1e-5)


@pytest.mark.parametrize("bad", [(1, 1, 1), (0, 1, 1, 1), (1, 1, 1, 9), (1.0, 1, 1, 1), "1111", (True, 1, 1, 1)])
def test_bad_blocks_are_refused_naming_what_is_expected(bad):
    with pytest.raises(TactileForceError, match="four residual-block counts per stage"):
        build_model("rgbmod", 0.25, bad)
    with pytest.raises(TactileForceError, match="blocks"):
        ModelSpec("rgbmod", 0.25, 0.25, bad)


def test_checkpoint_carries_blocks_and_a_file_without_them_is_read_from_its_keys(tmp_path):
    spec = ModelSpec("rgbmod+d", 0.25, 0.25, (1, 2, 1, 1))
    model = build_model("rgbmod+d", 0.25, (1, 2, 1, 1))
    save_checkpoint(tmp_path / "ours.pth", model, spec)
    got_model, got, ckpt = model_from_checkpoint(tmp_path / "ours.pth")
    assert got == spec and ckpt.meta["blocks"] == [1, 2, 1, 1]
    # a bare state_dict (the authors' format) says nothing: its keys hold one block per stage
    torch.save({"state_dict": build_model("d", 0.5, ONE).state_dict()}, tmp_path / "bare.pth")
    _, bare, _ = model_from_checkpoint(tmp_path / "bare.pth", variant="d", width=0.5)
    assert bare.blocks == ONE
    # metadata that is not four counts: refused before any work, naming the key
    torch.save({"state_dict": model.state_dict(), "tactile_force": {**spec.as_dict(), "blocks": [1, 1]}},
               tmp_path / "bad.pth")
    with pytest.raises(CheckpointError, match=r"tactile_force\.blocks.*four residual-block counts"):
        model_from_checkpoint(tmp_path / "bad.pth")
    # metadata that contradicts the keys: the strict load names the keys
    torch.save({"state_dict": model.state_dict(), "tactile_force": {**spec.as_dict(), "blocks": [2, 2, 2, 2]}},
               tmp_path / "lies.pth")
    with pytest.raises(CheckpointError, match="missing keys: .*layer1.1"):
        model_from_checkpoint(tmp_path / "lies.pth")


def test_export_records_blocks_and_a_manifest_without_them_means_resnet18(tmp_path):
    torch.manual_seed(0)
    spec = ModelSpec("rgbmod", 0.125, 1 / 8, ONE)
    b = export_bundle(ForceNet(build_model("rgbmod", 0.125, ONE).eval(), spec), tmp_path / "b1111",
                      ExportOptions(name="b1111"))
    assert b.manifest.architecture.blocks == [1, 1, 1, 1]
    full = export_bundle(ForceNet(build_model("rgbmod", 0.125).eval(), ModelSpec("rgbmod", 0.125, 1 / 8)),
                         tmp_path / "b2222", ExportOptions(name="b2222"))
    assert full.manifest.architecture.blocks == [2, 2, 2, 2]
    assert b.manifest.architecture.gmacs < full.manifest.architecture.gmacs
    assert b.manifest.architecture.macs_by_op["Conv"] < 0.75 * full.manifest.architecture.macs_by_op["Conv"]
    frame = np.random.default_rng(0).integers(0, 256, (2, 320, 240, 3), np.uint8)
    m = OnnxForceModel(b)
    try:
        assert np.all(np.isfinite(m.predict(frame)))
    finally:
        m.close()
    # a bundle written before the field existed (the shipped int8 RGBmod's manifest has none): ResNet-18's
    int8 = default_bundle_path().parent / "rgbmod_int8"
    raw = json.loads((int8 / "model.json").read_text())
    assert "blocks" not in raw["architecture"]
    assert load_bundle(int8).manifest.architecture.blocks == [2, 2, 2, 2]
    with pytest.raises(TypedJsonError, match="blocks"):
        from_json(Architecture, {**raw["architecture"], "blocks": [1, 1, 1]}, "architecture")
    # the field is read from the manifest (the file hash covers the graph, not the record)
    copy = tmp_path / "copy"
    shutil.copytree(int8, copy)
    raw["architecture"]["blocks"] = [1, 1, 1, 1]  # a claim the int8 graph (two blocks per stage) contradicts
    (copy / "model.json").write_text(json.dumps(raw))
    from tactile_force.edge.errors import BundleError

    with pytest.raises(BundleError, match=r"architecture.blocks \[1, 1, 1, 1\] makes 12 convolutions"):
        load_bundle(copy)


def test_ladder_text_names_fewer_blocks():
    rungs = parse_ladder("0.125x8, 0.25x4b1111,0.5x4B1211")
    assert rungs == (Rung(0.125, 8), Rung(0.25, 4, ONE), Rung(0.5, 4, (1, 2, 1, 1)))
    assert [r.name for r in rungs] == ["rgbmod-w0.125-s8", "rgbmod-w0.25-s4-b1111", "rgbmod-w0.5-s4-b1211"]
    assert [r.text for r in rungs] == ["0.125x8", "0.25x4b1111", "0.5x4b1211"]
    assert rungs[1].spec == ModelSpec("rgbmod", 0.25, 0.25, ONE)
    for bad in ("0.25x4b111", "0.25x4b1119", "0.25x4bx", "0.25by4"):
        with pytest.raises(CompressError, match="WIDTHxKbNNNN"):
            parse_ladder(bad)


def test_error_steps_say_what_each_step_down_costs():
    def rec(name, p99, vs_t, vs_l=None):
        r = {"name": name, "p99_ms": p99, "vs_teacher": {"re_mean": vs_t}}
        if vs_l is not None:
            r["vs_labels"] = {"re_mean": vs_l}
            r["teacher_vs_labels"] = {"re_mean": 0.05}
        return r

    records = [rec("cheap", 0.2, 0.10, 0.12), rec("wide", 0.9, 0.02, 0.06), rec("mid", 0.5, 0.05, 0.08)]
    ordered = error_steps(records)
    assert [r["name"] for r in ordered] == ["wide", "mid", "cheap"]
    assert ordered[0]["step"] == pytest.approx({"from": "teacher", "vs_teacher_re": 0.02, "vs_labels_re": 0.01})
    assert ordered[1]["step"] == pytest.approx({"from": "wide", "vs_teacher_re": 0.03, "vs_labels_re": 0.02})
    assert ordered[2]["step"] == pytest.approx({"from": "mid", "vs_teacher_re": 0.05, "vs_labels_re": 0.04})
    unlabelled = error_steps([rec("a", 1.0, 0.03), rec("b", 0.5, 0.07)])
    assert unlabelled[1]["step"]["vs_labels_re"] is None
    assert unlabelled[1]["step"]["vs_teacher_re"] == pytest.approx(0.04)


def test_shipped_manifests_still_load(tmp_path):
    for folder in ("rgbmod_int8", "d", "rgbmod_d"):
        path = Path(default_bundle_path()).parent / folder
        assert load_bundle(path).manifest.architecture.blocks == [2, 2, 2, 2]
    assert load_bundle(default_bundle_path()).manifest.architecture.blocks == [1, 1, 1, 1]
