"""Every reading carries its error bar: the conformal interval, its manifest
record, the runtime applying it, and every output that carries it.

The coverage tests are statistical with fixed seeds; their tolerance is derived from the
binomial spread of the test share and the Beta spread of split conformal coverage given
the calibration set, never a hard-coded result.
"""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tactile_force.edge.bundle.interval import ForceInterval, IntervalBin, IntervalError
from tactile_force.edge.bundle.manifest import manifest_from_json
from tactile_force.edge.bundle.store import load_bundle, write_bundle
from tactile_force.edge.errors import BundleError
from tactile_force.edge.fitting.interval import conformal_quantile, fit_interval, interval_coverage, min_points
from tactile_force.edge.outputs import CsvWriter, JsonlWriter
from tactile_force.edge.outputs.files import format_reading
from tactile_force.edge.reading import Flags, ForceReading, IntervalState

from tests.conftest import shared_data


def _hetero(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(estimate, truth) with an error that grows with the force and a bias at the ends."""
    y = rng.uniform(0.3, 19.0, n)
    f = y * (1 + rng.normal(0.0, 0.06, n)) + rng.normal(0.0, 0.25, n) + 0.4 * (y > 14)
    return f, y


@pytest.fixture(scope="module")
def fitted() -> ForceInterval:
    return fit_interval(*_hetero(np.random.default_rng(1), 3000), data="synthetic pairs")


# -- the interval of one reading ------------------------------------------------------------------
@settings(max_examples=300, deadline=None)
@given(force=st.floats(0.0, 15.0), saturated=st.booleans())
def test_interval_contains_the_estimate(fitted, force, saturated):
    lo, hi, state = fitted.bounds(force, saturated)
    assert 0.0 <= lo <= force <= hi
    assert (state is IntervalState.OPEN_ABOVE) == saturated
    assert math.isinf(hi) == saturated


def test_no_estimate_no_interval(fitted):
    lo, hi, state = fitted.bounds(math.nan)
    assert math.isnan(lo) and math.isnan(hi) and state is IntervalState.UNKNOWN
    r = ForceReading("s", 0, 0, math.nan, Flags.INVALID_INPUT)  # what the runtime emits without an estimate
    assert math.isnan(r.force_low_n) and math.isnan(r.force_high_n) and r.interval is IntervalState.UNKNOWN


def test_saturated_is_open_above(fitted):
    lo, hi, state = fitted.bounds(15.0, True)
    assert state is IntervalState.OPEN_ABOVE and hi == math.inf and 0 < lo < 15.0
    # below 15 N too (gel saturation seen): the upper bound is open, the lower one from the estimate's bin
    lo2, hi2, state2 = fitted.bounds(12.0, True)
    assert hi2 == math.inf and state2 is IntervalState.OPEN_ABOVE and lo2 == fitted.bounds(12.0)[0]


def test_below_range_lower_bound_is_zero_not_negative(fitted):
    lo, hi, state = fitted.bounds(0.2)
    assert lo == 0.0 and hi > 0.2 and state is IntervalState.KNOWN


def test_too_few_points_is_unknown_not_invented():
    assert (min_points(0.9), min_points(0.95), min_points(0.5)) == (9, 19, 1)
    rng = np.random.default_rng(2)
    f, y = _hetero(rng, 8)
    iv = fit_interval(f, y, 0.9)
    assert [b.q for b in iv.bins] == [None] and not iv.known
    assert iv.bounds(5.0)[2] is IntervalState.UNKNOWN and math.isnan(iv.bounds(5.0)[0])
    iv9 = fit_interval(*_hetero(rng, 9), 0.9)
    assert len(iv9.bins) == 1 and iv9.bins[0].q is not None  # 9 points: the largest score
    # a coverage too high for the data: unknown again
    assert not fit_interval(*_hetero(rng, 30), 0.99).known


def test_bins_merge_until_each_has_enough_points():
    rng = np.random.default_rng(3)
    f, y = _hetero(rng, 60)
    iv = fit_interval(f, y, 0.9)
    assert all(b.n >= min_points(0.9) for b in iv.bins) and sum(b.n for b in iv.bins) == iv.n == 60
    assert 1 < len(iv.bins) < 7  # 60 points cannot fill 7 bins of >= 9 unevenly spread forces


def test_conformal_quantile_is_the_finite_sample_rank():
    s = np.arange(1.0, 20.0)  # 19 scores
    assert conformal_quantile(s, 0.9) == 18.0  # ceil(20 * 0.9) = 18th smallest
    assert conformal_quantile(s, 0.95) == 19.0
    assert conformal_quantile(s[:10], 0.95) is None


def test_bad_input_names_the_argument():
    with pytest.raises(IntervalError, match="coverage"):
        fit_interval([1.0], [1.0], 1.5)
    with pytest.raises(IntervalError, match="2 estimates for 3"):
        fit_interval([1.0, 2.0], [1.0, 2.0, 3.0])
    with pytest.raises(IntervalError, match="edges_n"):
        fit_interval([1.0], [1.0], edges_n=(4.0, 2.0))


# -- coverage on held-out data ---------------------------------------------------------------------
def _tolerance(iv: ForceInterval, estimate: np.ndarray, m: int, sigmas: float = 4.0) -> tuple[float, float]:
    """Band for the observed coverage on ``m`` held-out pairs: stated coverage c minus, and
    c + 1/(n_b+1) plus, ``sigmas`` standard deviations of (test binomial share) + (Beta spread of
    each bin's coverage given its n_b calibration points), weighted by the test share per bin."""
    c = iv.coverage
    edges = [b.lo_n for b in iv.bins[1:]]
    k = np.searchsorted(edges, np.clip(estimate, 0, 15), side="right")
    w = np.bincount(k, minlength=len(iv.bins)) / k.size
    var_cal = sum(wb * wb * c * (1 - c) / (b.n + 2) for wb, b in zip(w, iv.bins))
    sd = math.sqrt(c * (1 - c) / m + var_cal)
    slack = max(1.0 / (b.n + 1) for b in iv.bins)
    return c - sigmas * sd, c + slack + sigmas * sd


def test_coverage_on_held_out_pairs_within_binomial_tolerance():
    rng = np.random.default_rng(20260)
    iv = fit_interval(*_hetero(rng, 1500))
    f, y = _hetero(rng, 4000)  # held out: drawn after the calibration pairs
    inside, known, _ = interval_coverage(iv, f, y)
    lo, hi = _tolerance(iv, f, known)
    assert known == f.size and lo <= inside / known <= hi, (inside / known, lo, hi)


def _virtual_presses(seed: int, n: int):
    """``n`` independent virtual DIGIT presses (indenter, place, force drawn afresh each time)."""
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions, paper_split, sample_contact

    digit = VirtualDigit(VirtualDigitOptions(seed=seed))
    rng = np.random.default_rng([seed, 21])
    names = list(paper_split("S1").test)
    frames, forces = [], []
    for _ in range(n):
        f = float(rng.uniform(1.0, 16.0))
        frames.append(digit.render(sample_contact(rng, names[int(rng.integers(len(names)))], 0.1), f).frame)
        forces.append(f)
    return np.stack(frames), np.array(forces)


def test_coverage_on_held_out_virtual_digit_presses():
    """The default bundle's model on presses of the S1 test indenters it never trained on:
    fitted on one seed's presses, the interval covers another seed's within tolerance."""
    from tactile_force.edge.model.onnx_model import OnnxForceModel
    from tactile_force.edge.scene import default_bundle_path

    model = OnnxForceModel(default_bundle_path(), threads=1)

    def estimates(frames):
        return np.concatenate([model.predict(frames[i:i + 2]) for i in range(0, len(frames), 2)]).astype(float)

    cal_frames, cal_truth = _virtual_presses(2111, 240)
    test_frames, test_truth = _virtual_presses(2112, 240)
    iv = fit_interval(estimates(cal_frames), cal_truth, 0.9, data="virtual presses seed 2111")
    f = estimates(test_frames)
    inside, known, rel = interval_coverage(iv, f, test_truth)
    lo, hi = _tolerance(iv, f, known)
    assert known == len(f) and lo <= inside / known <= hi, (inside / known, lo, hi)
    assert np.nanmedian(rel) < 1.0  # a real interval, not the whole range


# -- the manifest record ------------------------------------------------------------------------
def test_manifest_round_trip(rgb_bundle, tmp_path, fitted):
    b = load_bundle(rgb_bundle)
    b.manifest.interval = fitted
    out = write_bundle(tmp_path / "with_interval", b.onnx_path.read_bytes(), b.manifest).path
    back = load_bundle(out).manifest.interval
    assert back is not None and back.bins == fitted.bins and back.coverage == 0.9
    assert (back.data, back.n, back.method) == ("synthetic pairs", 3000, fitted.method)
    assert back.bounds(7.5) == fitted.bounds(7.5)
    raw = json.loads((out / "model.json").read_text())
    raw["interval"]["bins"][1]["lo_n"] = 99.0  # not contiguous
    with pytest.raises(BundleError, match="interval"):
        manifest_from_json(raw)
    raw = json.loads((out / "model.json").read_text())
    raw["interval"]["coverage"] = 1.0
    with pytest.raises(BundleError, match="interval.coverage"):
        manifest_from_json(raw)


# -- the runtime ------------------------------------------------------------------------------------
def _runtime_readings(bundle_path, frames_dir, background):
    from tactile_force.edge.gate.contact_gate import ContactGate
    from tactile_force.edge.model.onnx_model import OnnxForceModel
    from tactile_force.edge.runtime import ForceRuntime, Sensor
    from tactile_force.edge.sources import ReplayFolderSource

    gate = ContactGate()
    gate.capture_background(background)
    rt = ForceRuntime([Sensor("left", ReplayFolderSource(frames_dir), gate)], OnnxForceModel(bundle_path))
    try:
        return [r for _ in range(11) for r in rt.step()]
    finally:
        rt.close()


@pytest.fixture(scope="module")
def aurova_background():
    from tactile_force.edge.sources import load_background

    return load_background(shared_data("digit_backgrounds", "aurova_background_b.png"))


def _with_interval(src, dest, interval):
    b = load_bundle(src)
    b.manifest.interval = interval
    return write_bundle(dest, b.onnx_path.read_bytes(), b.manifest).path


def test_runtime_applies_the_interval(tmp_path, aurova_dir, aurova_background):
    from tactile_force.edge.scene import default_bundle_path

    src = load_bundle(default_bundle_path())
    iv = fit_interval(*_hetero(np.random.default_rng(4), 500), model_sha256=src.manifest.sha256)
    path = _with_interval(default_bundle_path(), tmp_path / "b", iv)
    readings = _runtime_readings(path, aurova_dir, aurova_background)
    est = [r for r in readings if math.isfinite(r.force_n) and not r.flags & Flags.NO_CONTACT]
    assert est, "no reading in contact"
    for r in est:
        assert (r.force_low_n, r.force_high_n, r.interval) == iv.bounds(r.force_n, bool(r.flags & Flags.SATURATED))
        assert r.force_low_n <= r.force_n <= r.force_high_n
    # fitted for another model (the graph changed after the fit): not applied, every reading unknown
    iv.model_sha256 = "0" * 64
    other = _with_interval(default_bundle_path(), tmp_path / "other", iv)
    assert all(r.interval is IntervalState.UNKNOWN and math.isnan(r.force_low_n)
               for r in _runtime_readings(other, aurova_dir, aurova_background))


def test_runtime_without_interval_says_unknown(rgb_bundle, aurova_dir, aurova_background):
    assert load_bundle(rgb_bundle).manifest.interval is None
    readings = _runtime_readings(rgb_bundle, aurova_dir, aurova_background)
    assert readings and all(r.interval is IntervalState.UNKNOWN and math.isnan(r.force_high_n) for r in readings)


def test_no_contact_reading_uses_the_gate_closed_bound():
    from tactile_force.edge.runtime.bounds import bound

    iv = fit_interval(*_hetero(np.random.default_rng(5), 200), no_contact_truth=np.r_[np.zeros(80), 0.3, 0.6])
    assert iv.no_contact_bounds() == (0.0, 0.0, IntervalState.KNOWN)  # 90 % of 82 gate-closed frames are 0 N
    r = ForceReading("s", 0, 0, 0.0, Flags.NO_CONTACT)
    bound(r, iv)
    assert (r.force_low_n, r.force_high_n, r.interval) == (0.0, 0.0, IntervalState.KNOWN)
    r = ForceReading("s", 0, 0, 0.0, Flags.NO_CONTACT)
    bound(r, fit_interval(*_hetero(np.random.default_rng(5), 200)))  # no gate-closed frames: unknown
    assert r.interval is IntervalState.UNKNOWN and math.isnan(r.force_high_n)


def test_frames_read_while_the_background_is_learnt_have_no_known_interval(aurova_dir, aurova_background):
    """No background given: the first frames are averaged into it and not judged; whatever they
    show (here presses of 1.1-7.4 N), their interval is unknown, never [0, the gate-closed bound]."""
    from tactile_force.edge.gate.contact_gate import ContactGate
    from tactile_force.edge.model.onnx_model import OnnxForceModel
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
    from tactile_force.edge.scene import default_bundle_path
    from tactile_force.edge.sources import ReplayFolderSource

    from tests.conftest import ListSource

    model = OnnxForceModel(default_bundle_path())
    iv = model.bundle.manifest.interval
    assert iv is not None and iv.no_contact_bounds()[2] is IntervalState.KNOWN  # a bound the gate-closed frames get

    def readings(source):
        rt = ForceRuntime([Sensor("left", source, ContactGate())], model, RuntimeOptions(deadline_ms=1e9),
                          owns_model=False)
        try:
            return [r for _ in range(20) for r in rt.step()]
        finally:
            rt.close()

    learning = [r for r in readings(ReplayFolderSource(aurova_dir)) if r.detail == "learning background"]
    assert len(learning) == ContactGate().options.background_frames
    assert all(r.truth_n > 1.0 for r in learning)
    for r in learning:
        assert Flags.NO_CONTACT in r.flags and r.interval is IntervalState.UNKNOWN, r
        assert math.isnan(r.force_low_n) and math.isnan(r.force_high_n)
    # once the background is settled, a frame judged without contact gets the gate-closed bound
    n = ContactGate().options.background_frames
    out = readings(ListSource([aurova_background[0]] * (n + 2)))
    assert [r.interval for r in out] == [IntervalState.UNKNOWN] * n + [IntervalState.KNOWN] * 2
    assert (out[-1].force_low_n, out[-1].force_high_n, out[-1].interval) == iv.no_contact_bounds()
    model.close()


# -- calibrate-force replaces the interval ---------------------------------------------------------
def test_calibrate_force_replaces_the_interval(tmp_path, aurova_dir):
    from tactile_force.edge.fitting.calibrate import calibrate_bundle
    from tactile_force.edge.scene import default_bundle_path

    bundle, _ = calibrate_bundle(default_bundle_path(), aurova_dir, tmp_path / "cal")
    iv = bundle.manifest.interval
    assert iv is not None and iv.n == 11 and "leave-one-out" in iv.data
    assert iv.model_sha256 == bundle.manifest.sha256 and len(iv.bins) == 1 and iv.bins[0].q is not None
    bundle2, _ = calibrate_bundle(default_bundle_path(), aurova_dir, tmp_path / "cal95", coverage=0.95)
    assert bundle2.manifest.interval.coverage == 0.95 and not bundle2.manifest.interval.known  # 11 < 19 points


# -- outputs --------------------------------------------------------------------------------------------
def _open_reading() -> ForceReading:
    return ForceReading("left", 5, 3, 15.0, Flags.SATURATED, force_low_n=13.5, force_high_n=math.inf,
                        interval=IntervalState.OPEN_ABOVE)


def test_csv_and_jsonl_columns(tmp_path):
    known = ForceReading("left", 4, 2, 6.0, force_low_n=5.0, force_high_n=7.25, interval=IntervalState.KNOWN)
    with CsvWriter(tmp_path / "r.csv") as w:
        w.write(known)
        w.write(_open_reading())
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    assert [(r["force_low_n"], r["force_high_n"], r["interval"]) for r in rows] == [
        ("5.0", "7.25", "known"), ("13.5", "inf", "open_above")]
    with JsonlWriter(tmp_path / "r.jsonl") as w:
        w.write(_open_reading())
        w.write(ForceReading("left", 6, 4, math.nan, Flags.INVALID_INPUT))
    lines = [json.loads(x) for x in open(tmp_path / "r.jsonl")]
    assert (lines[0]["force_low_n"], lines[0]["force_high_n"], lines[0]["interval"]) == (13.5, None, "open_above")
    assert (lines[1]["force_low_n"], lines[1]["force_high_n"], lines[1]["interval"]) == (None, None, "unknown")
    assert "[13.50, inf) N" in format_reading(_open_reading())  # the live status line


def test_ros2_diagnostics_keys_and_interval_message():
    pytest.importorskip("cyclonedds", reason="ROS 2 messages need cyclonedds (the 'ros2' extra)")
    from tactile_force.edge.outputs.ros2_messages import (
        DiagnosticArray,
        Vector3Stamped,
        diagnostic_message,
        interval_message,
        reading_payloads,
    )
    from tactile_force.edge.outputs.ros2_names import StampClock

    clock = StampClock(offset_ns=0)
    values = {kv.key: kv.value for kv in diagnostic_message(_open_reading(), clock).status[0].values}
    assert (values["force_low_n"], values["force_high_n"], values["interval"]) == ("13.5", "inf", "open_above")
    v = interval_message(_open_reading(), clock).vector
    assert (v.x, v.y, v.z) == (13.5, 15.0, math.inf)
    got = {t: (ty, d) for t, ty, d in reading_payloads(_open_reading(), clock, "/tactile/force")}
    assert got["/tactile/force/interval"][0] == "geometry_msgs/msg/Vector3Stamped"
    assert Vector3Stamped.deserialize(got["/tactile/force/interval"][1]).vector.z == math.inf
    assert DiagnosticArray.deserialize(got["/tactile/force/diagnostics"][1]).status[0].values


def test_interval_bin_record_is_typed():
    iv = ForceInterval(bins=[IntervalBin(0.0, 5.0, 10, 0.2), IntervalBin(5.0, None, 10, None)])
    iv.check()
    assert iv.bounds(7.0)[2] is IntervalState.UNKNOWN and iv.bounds(2.0) == (1.0, 3.0, IntervalState.KNOWN)
    with pytest.raises(ValueError, match="only the last bin"):
        ForceInterval(bins=[IntervalBin(0.0, None, 1, 0.1), IntervalBin(5.0, None, 1, 0.1)]).check()


def test_bundle_show_names_the_interval(rgb_bundle, tmp_path, fitted, capsys):
    from tactile_force.edge.cli import main as cli_main

    assert cli_main(["bundle", "show", str(rgb_bundle)]) == 0
    assert "interval  NONE" in capsys.readouterr().out
    path = _with_interval(rgb_bundle, tmp_path / "shown", fitted)
    assert cli_main(["bundle", "show", str(path)]) == 0
    assert "interval  0.9 coverage" in capsys.readouterr().out
