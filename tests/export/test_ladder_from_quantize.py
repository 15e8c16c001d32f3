"""The bundle ladder chooses by the error report quantize_bundle really writes."""

from __future__ import annotations

import math

import pytest

torch = pytest.importorskip("torch", reason="building real bundles needs the 'export' extra (torch)")

from tactile_force.edge.model.ladder import choose_bundle, pick_from_ladder  # noqa: E402
from tactile_force.export import ExportOptions, QuantizeOptions, build_model, export_bundle, quantize_bundle  # noqa: E402


@pytest.fixture(scope="module")
def ladder(module_tmp, aurova):
    """Three bundles made by quantize_bundle from one fp32 export, each with a measured RE vs labels."""
    torch.manual_seed(3)
    model = build_model("rgbmod", 0.25).eval()
    with torch.no_grad():  # outputs in the grasp's range so RE is meaningful
        model.fc4.bias.fill_(6.0)
    fp32 = export_bundle(model, module_tmp / "lad_fp32",
                         ExportOptions(variant="rgbmod", width=0.25, input_scale=0.25, parity_data=aurova))
    out = []
    for name, opts in (("lad_int8", QuantizeOptions(mode="int8-static")),
                       ("lad_dyn", QuantizeOptions(mode="int8-dynamic")),
                       ("lad_fp16", QuantizeOptions(mode="fp16"))):
        out.append(quantize_bundle(fp32, module_tmp / name, opts, calibration=aurova))
    return out


def test_every_quantized_bundle_carries_a_real_score(ladder):
    for b in ladder:
        assert b.manifest.error is not None and b.manifest.error.vs_truth is not None
        assert math.isfinite(b.manifest.error_score())
        assert b.manifest.error_score() == b.manifest.error.vs_truth.re_mean


def test_ladder_of_three_quantized_bundles_picks_the_most_accurate_that_fits(ladder):
    paths = [str(b.path) for b in ladder]
    scores = {str(b.path): b.manifest.error_score() for b in ladder}
    assert len(set(scores.values())) == 3, scores  # three different measured errors
    model, choice = choose_bundle(paths, budget_ms=1e6, runs=3)
    best = min(scores, key=scores.get)
    assert str(model.bundle.path) == best and "most accurate" in choice.reason
    assert choice.score == scores
    # the most accurate does not fit: the next most accurate that does is chosen
    ranked = sorted(scores, key=scores.get)
    p99 = {ranked[0]: 5.0, ranked[1]: 0.9, ranked[2]: 0.5}
    key, reason = pick_from_ladder(paths, p99, scores, budget_ms=1.0)
    assert key == ranked[1] and "most accurate that fits" in reason
    key, reason = pick_from_ladder(paths, p99, scores, budget_ms=0.1)
    assert key == ranked[2] and "no bundle fits" in reason
