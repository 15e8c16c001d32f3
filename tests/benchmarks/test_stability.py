"""``python -m benchmarks stability``: it measures every shipped bundle (found by its
model.json), each through the depth stage its manifest records; no timing assertions."""

from __future__ import annotations

import numpy as np
from tactile_force.edge import OnnxForceModel
from tactile_force.edge.scene import default_bundle_path

from benchmarks.stability import SHIPPED, Case, models_to_test, run_case


def test_shipped_only_lists_every_bundle_in_edge_models_the_default_first():
    found = models_to_test(quick=True, shipped_only=True)
    on_disk = sorted(p.parent for p in default_bundle_path().parent.glob("*/model.json"))
    assert sorted(path for _, _, path, _ in found) == on_disk and on_disk
    assert found[0][2] == default_bundle_path() and {w for *_, w in found} == {SHIPPED}
    assert all(cfg.startswith(f"shipped {path.name} (") for cfg, _, path, _ in found)


def test_a_shipped_depth_bundle_flags_bad_frames_with_no_non_finite_output():
    d = next(path for cfg, _, path, _ in models_to_test(quick=True, shipped_only=True) if "(d)" in cfg)
    bad = [np.full((320, 240, 3), np.nan, np.float32), np.full((320, 240, 3), np.inf, np.float32)]
    background = np.full((1, 320, 240, 3), 120, np.uint8)  # the no-contact frames the gate learns
    model = OnnxForceModel(d, threads=1)
    try:
        out = run_case(model, Case("nan", bad, [8.0, 8.0], "invalid_input"), background, depth_factory=None)
    finally:
        model.close()
    assert out.nonfinite == 0 and out.flags_ok == 1.0
    assert all("invalid_input" in f for f in out.flags)
