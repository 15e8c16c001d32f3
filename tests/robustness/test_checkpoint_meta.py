"""Checkpoint metadata is validated when the file is loaded, before any export work."""

from __future__ import annotations

import pytest
import torch
from hypothesis import example, given
from tactile_force.export import onnx_export
from tactile_force.export.checkpoint import CheckpointError, save_checkpoint
from tactile_force.export.onnx_export import ExportOptions, export_bundle
from tactile_force.export.zoo import ModelSpec, build_model

from benchmarks.robustness import checkpoint_metas, probe_checkpoint_meta

from .conftest import ROBUST


@ROBUST
@given(checkpoint_metas())
@example({"width": "abc"})  # TypeError/ValueError traceback at 9ed225d
@example([1, 2])  # a list as metadata: traceback at 9ed225d
@example({"note": "TENSOR"})  # failed only after the full export at 9ed225d
def test_metadata_is_accepted_or_refused_naming_the_key(tmp_path_factory, meta):
    v = probe_checkpoint_meta(tmp_path_factory.mktemp("ckpt"), meta)
    assert v.ok, v


@pytest.mark.parametrize("extra, key", [({"width": "abc"}, "width"), ({"note": torch.zeros(3)}, "note"),
                                        ({"input_scale": 3}, "input_scale"), ({"variant": "resnet"}, "variant")])
def test_bad_metadata_is_refused_before_any_export_work(tmp_path, monkeypatch, extra, key):
    path = tmp_path / "bad.pth"
    model = build_model("rgbmod", 0.25)
    torch.save({"state_dict": model.state_dict(),
                "tactile_force": {**ModelSpec("rgbmod", 0.25, 0.25).as_dict(), **extra}}, path)

    def no_export(*a, **kw):
        raise AssertionError("export work started before the metadata was checked")

    monkeypatch.setattr(onnx_export, "to_onnx", no_export)
    with pytest.raises(CheckpointError, match=rf"bad\.pth: metadata 'tactile_force\.{key}'"):
        export_bundle(path, tmp_path / "out", ExportOptions())
    assert not (tmp_path / "out").exists()


def test_list_metadata_is_named(tmp_path):
    path = tmp_path / "list.pth"
    torch.save({"state_dict": {"w": torch.zeros(1)}, "tactile_force": [1, 2]}, path)
    from tactile_force.export.checkpoint import load_checkpoint

    with pytest.raises(CheckpointError, match=r"list\.pth: metadata 'tactile_force' is a list; expected a dict"):
        load_checkpoint(path)


def test_our_own_checkpoints_still_load(tmp_path):
    from tactile_force.export.checkpoint import load_checkpoint

    p = save_checkpoint(tmp_path / "ours.pth", build_model("dmod", 0.25), ModelSpec("dmod", 0.25, 0.25),
                        {"trained_on": "unit test", "split": "S1", "best_epoch": 3})
    assert load_checkpoint(p).meta["best_epoch"] == 3
