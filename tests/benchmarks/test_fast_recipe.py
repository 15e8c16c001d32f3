"""The reference recipe's fast-bundle entry: its config, and the install refusing a bundle that
misses the RE goal against the shipped int8 RGBmod (nothing is written into edge/models)."""

from __future__ import annotations

import dataclasses
import shutil

import pytest
from tactile_force.edge.bundle.store import load_bundle, write_bundle
from tactile_force.edge.scene import default_bundle_path

from benchmarks import reference


def test_fast_config_has_one_block_per_stage_and_its_own_name():
    cfg = reference.CONFIGS[reference.FAST_MODEL]
    assert cfg.blocks == (1, 1, 1, 1) and cfg.variant == "rgbmod" and cfg.k == 4
    assert cfg.name == reference.FAST_MODEL and cfg.name.endswith("-b1111")
    assert reference.CONFIGS[reference.DEFAULT_MODEL].name == "rgbmod-w0.25-s4"  # ResNet-18's: no suffix
    assert dataclasses.replace(cfg, epochs=1).blocks == (1, 1, 1, 1)  # --epochs keeps the blocks


def test_install_fast_bundle_refuses_one_too_far_from_the_int8_rgbmod(tmp_path):
    src = load_bundle(reference.int8_bundle_path())
    m = src.manifest
    assert m.error is not None and m.error.vs_truth is not None
    worse = dataclasses.replace(m.error.vs_truth, re_mean=m.error.vs_truth.re_mean + 0.05)
    m.error = dataclasses.replace(m.error, fp32_vs_truth=worse)  # the fp32 graph's RE is what is checked
    for kind in ("int8", "fp32"):  # a trained model's folder: both bundles
        write_bundle(tmp_path / "candidate" / kind, src.onnx_path.read_bytes(), m)
    fast = default_bundle_path()
    before = (fast / "model.json").read_bytes() if fast.exists() else None
    with pytest.raises(reference.FastBundleError, match="more than 0.03 above the int8 RGBmod's"):
        reference.install_fast_bundle(tmp_path / "candidate")
    assert ((fast / "model.json").read_bytes() if fast.exists() else None) == before
    shutil.rmtree(tmp_path / "candidate")
