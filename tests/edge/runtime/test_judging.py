"""edge/runtime/judging.py on its own: range flags, saturation, out_of_distribution (colours, another
sensor), the background_mismatch / invalid_input verdict's detail, the data_stats check made
on first use. Real GateResult and DataStatsCheck; the model is a plain record carrying a
manifest (no inference is run here)."""

from __future__ import annotations

import logging
import math
from types import SimpleNamespace

import numpy as np
import pytest
from tactile_force.edge.bundle.data_stats import DataStats
from tactile_force.edge.gate.contact_gate import GateResult
from tactile_force.edge.reading import MAX_VALID_FORCE_N, MIN_VALID_FORCE_N, Flags
from tactile_force.edge.runtime.judging import EstimateJudge, gate_verdict

ROWS, COLS = 20, 15


def _model(stats: DataStats | None) -> object:
    return SimpleNamespace(bundle=SimpleNamespace(name="test-bundle", manifest=SimpleNamespace(data_stats=stats)))


def _stats(**kw) -> DataStats:
    n = ROWS * COLS * 3
    base = dict(frames=10, cell_lo=[100.0] * n, cell_hi=[140.0] * n, margin=0.0, max_outside_frac=0.10,
                contact_area_frac_max=0.2, deformation_max=30.0)
    base.update(kw)
    return DataStats(**base)  # type: ignore[arg-type]


def _gate(area_px: int = 1000, saturation: bool = False, deformation: float = 5.0,
          thumb_value: int = 120) -> GateResult:
    full = np.zeros((320, 240), np.uint8)
    g = GateResult(True, area_px, saturation, full, full, 1, True)
    g.deformation = deformation
    g.thumb = np.full((ROWS, COLS, 3), thumb_value, np.uint8)
    return g


def test_range_flags_and_clamping():
    j = EstimateJudge(_model(_stats()))
    assert j.estimate(5.0, _gate()) == (Flags.NONE, 5.0, "")
    flags, force, _ = j.estimate(MIN_VALID_FORCE_N - 0.5, _gate())
    assert flags == Flags.BELOW_RANGE and force == MIN_VALID_FORCE_N - 0.5
    flags, force, _ = j.estimate(-2.0, _gate())
    assert flags == Flags.BELOW_RANGE and force == 0.0  # clamped at 0 N
    flags, force, _ = j.estimate(MAX_VALID_FORCE_N + 3.0, _gate())
    assert flags == Flags.SATURATED and force == MAX_VALID_FORCE_N  # a lower bound


@pytest.mark.parametrize("raw", [math.nan, math.inf, -math.inf])
def test_non_finite_estimate_is_invalid_input_naming_the_value_or_the_error(raw):
    j = EstimateJudge(_model(_stats()))
    flags, force, detail = j.estimate(raw, _gate())
    assert flags == Flags.INVALID_INPUT and math.isnan(force) and detail == f"model returned {raw}"
    flags, _, detail = j.estimate(raw, _gate(), "inference failed: RuntimeError: x")
    assert flags == Flags.INVALID_INPUT and detail == "inference failed: RuntimeError: x"


def test_saturation_seen_and_contact_beyond_the_data_are_saturated_with_the_force_kept():
    j = EstimateJudge(_model(_stats()))
    flags, force, detail = j.estimate(4.0, _gate(saturation=True))
    assert flags == Flags.SATURATED and force == 4.0 and detail == "gel saturation seen in the frame"
    flags, force, detail = j.estimate(4.0, _gate(area_px=int(0.5 * 320 * 240)))
    assert flags == Flags.SATURATED and force == 4.0 and "contact area 50 %" in detail and "lower bound" in detail
    flags, _, detail = j.estimate(4.0, _gate(deformation=80.0))
    assert flags == Flags.SATURATED and detail.startswith("deformation 80 grey levels exceeds")


def test_out_of_distribution_colours_keep_the_force_and_join_the_detail():
    j = EstimateJudge(_model(_stats()))
    flags, force, detail = j.estimate(4.0, _gate(thumb_value=200))
    assert flags == Flags.OUT_OF_DISTRIBUTION and force == 4.0
    assert detail.startswith("100 % of the frame's low-resolution colours lie outside")
    flags, _, detail = j.estimate(4.0, _gate(saturation=True, thumb_value=200))
    assert flags == Flags.SATURATED | Flags.OUT_OF_DISTRIBUTION
    assert detail.startswith("gel saturation seen in the frame; 100 % of the frame's")


def test_another_sensor_adds_out_of_distribution_also_to_a_failed_estimate():
    j = EstimateJudge(_model(_stats()))
    why = "sensor left: serial D20001 is not the calibration's D20002"
    assert j.estimate(4.0, _gate(), foreign=why) == (Flags.OUT_OF_DISTRIBUTION, 4.0, why)
    flags, _, detail = j.estimate(4.0, _gate(saturation=True), foreign=why)
    assert detail == f"gel saturation seen in the frame; {why}"
    flags, force, detail = j.estimate(math.nan, _gate(), foreign=why)
    assert flags == Flags.INVALID_INPUT | Flags.OUT_OF_DISTRIBUTION and math.isnan(force)
    assert detail == f"model returned nan; {why}"


def test_data_stats_check_is_made_on_first_use_and_off_without_data_stats(caplog):
    j = EstimateJudge(_model(None))
    with caplog.at_level(logging.WARNING, logger="tactile_force.edge.bundle.data_stats"):
        assert j.estimate(math.nan, _gate())[0] == Flags.INVALID_INPUT
        assert "data_stats" not in caplog.text  # not built for a failed estimate
        assert j.estimate(4.0, _gate(area_px=int(0.9 * 320 * 240), thumb_value=250)) == (Flags.NONE, 4.0, "")
    assert caplog.text.count("test-bundle: manifest has no data_stats") == 1
    assert j.stats_check() is j.stats_check() and not j.stats_check().active


def test_gate_verdict_details():
    full = np.zeros((320, 240), np.uint8)
    g = GateResult(False, 0, False, full, full, 1, True)
    g.invalid = "colour order looks RGB, expected BGR"
    assert gate_verdict("left", 7, g, 30) == (Flags.INVALID_INPUT,
                                              "left frame 7: colour order looks RGB, expected BGR")
    g.invalid, g.mismatch = "", "the gel moved"
    flags, detail = gate_verdict("right", 7, g, 30)
    assert flags == Flags.BACKGROUND_MISMATCH
    assert detail == ("right: background mismatch: the gel moved (background re-learnt after 30 stable frames "
                      "without a contact-like blob, or as soon as a frame fits again)")
    flags, detail = gate_verdict("right", 7, g, 0)
    assert detail == "right: background mismatch: the gel moved (call ContactGate.relearn() with the gripper open)"
