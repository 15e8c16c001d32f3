"""edge/runtime/judging.py on its own: range flags, saturation, out_of_distribution (colours, another
sensor), the background_mismatch / invalid_input verdict's detail, no_contact and a pressed
background, the data_stats check made on first use, the error bar applied where the reading
is made. Real GateResult, DataStatsCheck and ForceInterval; the bundle is a plain record
carrying a manifest (no inference is run here)."""

from __future__ import annotations

import logging
import math
from types import SimpleNamespace

import numpy as np
import pytest
from tactile_force.edge.bundle.data_stats import DataStats
from tactile_force.edge.fitting.interval import fit_interval
from tactile_force.edge.frames import TimedFrame
from tactile_force.edge.gate import ContactGate, GateOptions, GateResult
from tactile_force.edge.reading import MAX_VALID_FORCE_N, MIN_VALID_FORCE_N, Flags, IntervalState, StageLatency
from tactile_force.edge.runtime.judging import Judge, gate_verdict

ROWS, COLS = 20, 15


def _bundle(stats: DataStats | None, interval=None) -> object:
    return SimpleNamespace(name="test-bundle", path="test-bundle",
                           manifest=SimpleNamespace(data_stats=stats, interval=interval, sha256=""))


TF = TimedFrame(np.zeros((320, 240, 3), np.uint8), 123, 7, truth_n=4.5)


def _est(j: Judge, raw: float, g: GateResult, error: str = "", foreign: str = "") -> tuple[Flags, float, str]:
    r = j.estimate("left", TF, raw, g, StageLatency(), error, foreign)
    assert (r.sensor, r.timestamp_ns, r.frame_index, r.truth_n, r.contact_area_px) == ("left", 123, 7, 4.5, g.area_px)
    assert r.raw_force_n == raw or math.isnan(raw)
    return r.flags, r.force_n, r.detail


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
    j = Judge(_bundle(_stats()))
    assert _est(j, 5.0, _gate()) == (Flags.NONE, 5.0, "")
    flags, force, _ = _est(j, MIN_VALID_FORCE_N - 0.5, _gate())
    assert flags == Flags.BELOW_RANGE and force == MIN_VALID_FORCE_N - 0.5
    flags, force, _ = _est(j, -2.0, _gate())
    assert flags == Flags.BELOW_RANGE and force == 0.0  # clamped at 0 N
    flags, force, _ = _est(j, MAX_VALID_FORCE_N + 3.0, _gate())
    assert flags == Flags.SATURATED and force == MAX_VALID_FORCE_N  # a lower bound


@pytest.mark.parametrize("raw", [math.nan, math.inf, -math.inf])
def test_non_finite_estimate_is_invalid_input_naming_the_value_or_the_error(raw):
    j = Judge(_bundle(_stats()))
    flags, force, detail = _est(j, raw, _gate())
    assert flags == Flags.INVALID_INPUT and math.isnan(force) and detail == f"model returned {raw}"
    flags, _, detail = _est(j, raw, _gate(), "inference failed: RuntimeError: x")
    assert flags == Flags.INVALID_INPUT and detail == "inference failed: RuntimeError: x"


def test_saturation_seen_and_contact_beyond_the_data_are_saturated_with_the_force_kept():
    j = Judge(_bundle(_stats()))
    flags, force, detail = _est(j, 4.0, _gate(saturation=True))
    assert flags == Flags.SATURATED and force == 4.0 and detail == "gel saturation seen in the frame"
    flags, force, detail = _est(j, 4.0, _gate(area_px=int(0.5 * 320 * 240)))
    assert flags == Flags.SATURATED and force == 4.0 and "contact area 50 %" in detail and "lower bound" in detail
    flags, _, detail = _est(j, 4.0, _gate(deformation=80.0))
    assert flags == Flags.SATURATED and detail.startswith("deformation 80 grey levels exceeds")


def test_out_of_distribution_colours_keep_the_force_and_join_the_detail():
    j = Judge(_bundle(_stats()))
    flags, force, detail = _est(j, 4.0, _gate(thumb_value=200))
    assert flags == Flags.OUT_OF_DISTRIBUTION and force == 4.0
    assert detail.startswith("100 % of the frame's low-resolution colours lie outside")
    flags, _, detail = _est(j, 4.0, _gate(saturation=True, thumb_value=200))
    assert flags == Flags.SATURATED | Flags.OUT_OF_DISTRIBUTION
    assert detail.startswith("gel saturation seen in the frame; 100 % of the frame's")


def test_another_sensor_adds_out_of_distribution_also_to_a_failed_estimate():
    j = Judge(_bundle(_stats()))
    why = "sensor left: serial D20001 is not the calibration's D20002"
    assert _est(j, 4.0, _gate(), foreign=why) == (Flags.OUT_OF_DISTRIBUTION, 4.0, why)
    flags, _, detail = _est(j, 4.0, _gate(saturation=True), foreign=why)
    assert detail == f"gel saturation seen in the frame; {why}"
    flags, force, detail = _est(j, math.nan, _gate(), foreign=why)
    assert flags == Flags.INVALID_INPUT | Flags.OUT_OF_DISTRIBUTION and math.isnan(force)
    assert detail == f"model returned nan; {why}"


def test_data_stats_check_is_made_on_first_use_and_off_without_data_stats(caplog):
    j = Judge(_bundle(None))
    with caplog.at_level(logging.WARNING, logger="tactile_force.edge.bundle.data_stats"):
        assert _est(j, math.nan, _gate())[0] == Flags.INVALID_INPUT
        assert "data_stats" not in caplog.text  # not built for a failed estimate
        assert _est(j, 4.0, _gate(area_px=int(0.9 * 320 * 240), thumb_value=250)) == (Flags.NONE, 4.0, "")
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


def _interval():
    rng = np.random.default_rng(5)
    y = rng.uniform(0.5, 15.0, 200)
    return fit_interval(y * (1 + rng.normal(0, 0.08, y.size)), y, no_contact_truth=np.r_[np.zeros(80), 0.3, 0.6])


def test_every_reading_gets_its_error_bar_where_it_is_made():
    iv = _interval()
    j = Judge(_bundle(_stats(), iv))
    assert j.interval is iv
    r = j.estimate("left", TF, 5.0, _gate(), StageLatency())
    assert (r.force_low_n, r.force_high_n, r.interval) == iv.bounds(5.0, False)
    r = j.estimate("left", TF, MAX_VALID_FORCE_N + 3.0, _gate(), StageLatency())
    assert r.interval is IntervalState.OPEN_ABOVE and r.force_high_n == math.inf
    r = j.estimate("left", TF, math.nan, _gate(), StageLatency())  # no force, no error bar
    assert r.interval is IntervalState.UNKNOWN and math.isnan(r.force_low_n)
    assert Judge(_bundle(_stats())).estimate("left", TF, 5.0, _gate(), StageLatency()).interval is IntervalState.UNKNOWN


def test_a_gated_frame_is_judged_without_the_model():
    j = Judge(_bundle(_stats(), _interval()))
    gate = ContactGate(GateOptions(relearn_frames=30))
    closed = GateResult(False, 12, False, np.zeros((320, 240), np.uint8), np.zeros((320, 240), np.uint8), 1, True)
    r = j.gated("left", TF, closed, StageLatency(), "", gate)
    assert (r.flags, r.force_n, r.detail, r.contact_area_px) == (Flags.NO_CONTACT, 0.0, "", 12)
    assert (r.force_low_n, r.force_high_n, r.interval) == (0.0, 0.0, IntervalState.KNOWN)  # the gate-closed bound
    closed.background_ready = False  # learning its background: not judged, interval unknown
    r = j.gated("left", TF, closed, StageLatency(), "", gate)
    assert r.detail == "learning background" and r.force_n == 0.0 and r.interval is IntervalState.UNKNOWN
    r = j.gated("left", TF, closed, StageLatency(), "the background looks pressed", gate)
    assert r.flags == Flags.NO_CONTACT | Flags.BACKGROUND_MISMATCH and math.isnan(r.force_n)
    assert r.detail == "the background looks pressed" and r.interval is IntervalState.UNKNOWN
    closed.mismatch = "the gel moved"
    r = j.gated("left", TF, closed, StageLatency(), "", gate)
    assert r.flags == Flags.BACKGROUND_MISMATCH and math.isnan(r.force_n) and "after 30 stable frames" in r.detail
    r = j.invalid("left", TF, StageLatency(), "depth stage failed: x", 40)
    assert (r.flags, r.detail, r.contact_area_px) == (Flags.INVALID_INPUT, "depth stage failed: x", 40)
    assert math.isnan(r.force_n) and math.isnan(r.raw_force_n)
