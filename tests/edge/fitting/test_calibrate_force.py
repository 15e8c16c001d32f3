"""Per-sensor force calibration: the monotone fit, its refusals, the written bundle in the runtime."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from tactile_force.edge import AuthorsDataset, BundleError, default_bundle_path, load_bundle
from tactile_force.edge.bundle.force_calibration import ForceCalibration
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.data.dataset import AuthorsDatasetWriter
from tactile_force.edge.fitting.force_calibration import (
    CalibrationLimits,
    CalibrationRefused,
    fit_force_calibration,
    fit_knots,
    pav,
    spearman,
)
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.runtime import ForceRuntime, Sensor
from tactile_force.edge.sources import ReplayFolderSource, load_background

from tests.conftest import shared_data

finite = st.floats(min_value=-5, max_value=30, allow_nan=False, allow_infinity=False)


# -- the fit --------------------------------------------------------------------------------
@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(finite, st.floats(0.2, 20)), min_size=3, max_size=30),
       st.sampled_from(["isotonic", "linear"]))
@example([(2.0, 1.0), (2.0, 1.0), (3.0, 19.999999999999996)], "isotonic")  # top level a rounding step under 20 N
@example([(2.0, 1e-15), (3.0, 5.0), (4.0, 9.0)], "isotonic")  # bottom level a rounding step over 0 N
def test_fitted_map_is_monotone_everywhere(points, method):
    raw = np.array([p[0] for p in points])
    truth = np.array([p[1] for p in points])
    try:
        xs, ys = fit_knots(raw, truth, method)
    except CalibrationRefused:  # only when the truth does not increase with the estimate
        assert np.ptp(raw) == 0 or np.cov(raw, truth)[0, 1] <= 1e-9 or spearman(raw, truth) <= 0 or method == "linear"
        return
    cal = ForceCalibration(xs, ys)
    cal.check()
    grid = np.linspace(min(xs) - 10, max(xs) + 10, 500)
    out = cal.apply(grid)
    assert np.all(np.diff(out) >= -1e-5)
    assert out.min() >= 0.0 and out.max() <= 20.0 + 1e-4
    inplace = cal.apply_inplace(grid.astype(np.float32).copy())
    np.testing.assert_allclose(inplace, out, rtol=1e-5, atol=1e-4)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-50, 50), min_size=1, max_size=40))
def test_pav_is_the_least_squares_isotonic_fit(values):
    y = np.array(values)
    fit, vals, blocks = pav(y)
    assert np.all(np.diff(fit) >= -1e-9)
    assert fit.mean() == pytest.approx(y.mean(), abs=1e-6)  # blocks hold their means
    for v, b in zip(vals, blocks):
        assert v == pytest.approx(y[b].mean(), abs=1e-6)
    # no monotone perturbation of a block's value lowers the squared error
    base = ((fit - y) ** 2).sum()
    for b in blocks:
        for d in (-1e-3, 1e-3):
            g = fit.copy()
            g[b] += d
            if np.all(np.diff(g) >= 0):
                assert ((g - y) ** 2).sum() >= base - 1e-9


def test_calibration_corrects_a_compressive_model():
    truth = np.linspace(1.0, 12.0, 12)
    raw = 7.5 * (1 - np.exp(-truth / 5))  # levels off like the default bundle on real frames
    cal = fit_force_calibration(raw, truth)
    assert cal.loo_after.mae_mean < 0.3 * cal.loo_before.mae_mean
    np.testing.assert_allclose(cal.apply(raw), truth, atol=1e-4)
    # harder than any calibration press: still increasing, and reaches the runtime's saturation
    assert cal.apply(np.array([raw.max() + 0.5]))[0] > truth.max()
    assert cal.apply(np.array([raw.max() + 50]))[0] >= 15.0
    assert math.isnan(cal.apply(np.array([np.nan]))[0])
    assert cal.spearman == pytest.approx(1.0)


def test_spearman_handles_ties():
    assert spearman(np.array([1, 2, 2, 3]), np.array([1, 2, 2, 3])) == pytest.approx(1.0)
    assert spearman(np.array([1, 2, 3, 4]), np.array([4, 3, 2, 1])) == pytest.approx(-1.0)


@pytest.mark.parametrize("raw,truth,words", [
    (np.arange(7.0), np.arange(7.0) + 1, "only 7 labelled frame"),
    (np.arange(10.0), np.linspace(5, 7.5, 10), "span only 2.50 N"),
    (np.arange(10.0), np.array([5, 1, 9, 2, 8, 3, 7, 4, 6, 10.0]), "Spearman"),
    (np.arange(10.0), np.array([1, 2, 3, np.nan, 5, 6, 7, 8, 9, 10]), "NaN"),
    (np.array([1, 2, np.inf, 4, 5, 6, 7, 8, 9, 10.0]), np.arange(10.0) + 1, "non-finite estimate"),
])
def test_refusals_name_the_problem(raw, truth, words):
    with pytest.raises(CalibrationRefused, match=words):
        fit_force_calibration(raw, truth)


def test_limits_are_options():
    raw = np.arange(6.0)
    cal = fit_force_calibration(raw, raw * 2 + 1, limits=CalibrationLimits(min_frames=5))
    assert cal.frames == 6


def test_manifest_rejects_a_non_monotone_map():
    cal = ForceCalibration([0.0, 1.0, 2.0], [0.0, 2.0, 1.0])
    with pytest.raises(ValueError, match="non-decreasing"):
        cal.check()


# -- the command and the bundle -------------------------------------------------------------
@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    data = shared_data("aurova_digit_grasp")
    out = tmp_path_factory.mktemp("cal") / "calibrated"
    rc = cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(data), "--out", str(out)])
    assert rc == 0
    return out


def test_calibrated_bundle_verifies_and_applies_its_map(calibrated, aurova_dir):
    b = load_bundle(calibrated)
    src = load_bundle(default_bundle_path())
    assert b.manifest.sha256 == src.manifest.sha256  # same model bytes
    cal = b.manifest.force_calibration
    assert cal is not None and cal.frames == 11 and cal.model_sha256 == src.manifest.sha256
    assert cal.loo_after.mae_mean < cal.loo_before.mae_mean
    assert b.manifest.provenance.calibrated_from.sha256 == src.manifest.sha256
    ds = AuthorsDataset(aurova_dir)
    frame = ds[len(ds) - 1].frame[None]
    raw = OnnxForceModel(calibrated, calibrate=False).predict(frame)
    got = OnnxForceModel(calibrated).predict(frame)
    assert got[0] == pytest.approx(float(cal.apply(raw)[0]), abs=1e-4)
    assert abs(got[0] - ds[len(ds) - 1].force_n) < abs(raw[0] - ds[len(ds) - 1].force_n)


def test_calibrated_bundle_runs_in_the_runtime(calibrated, aurova_dir):
    gate = ContactGate()
    gate.capture_background(load_background(shared_data("digit_backgrounds", "aurova_background_b.png")))
    rt = ForceRuntime([Sensor("left", ReplayFolderSource(aurova_dir), gate)], OnnxForceModel(calibrated))
    readings = [r for _ in range(11) for r in rt.step()]
    truth = np.array([r.truth_n for r in readings])
    force = np.array([r.force_n for r in readings])
    assert np.all(np.isfinite(force))
    # calibrated on these very frames: every reading within 1 N (the raw model is 2.7 N off on average)
    assert np.abs(force - truth).max() < 1.0


def test_a_calibration_for_another_model_is_refused(calibrated, tmp_path):
    from tactile_force.edge import write_bundle

    b = load_bundle(calibrated)
    other = b.onnx_path.read_bytes() + b"\x32\x01x"  # a doc_string: other bytes, same graph, calibration kept
    write_bundle(tmp_path / "other", other, b.manifest)
    with pytest.raises(BundleError, match="force_calibration was fitted for model"):
        OnnxForceModel(tmp_path / "other")


def _dataset(tmp_path, forces, frames):
    with AuthorsDatasetWriter(tmp_path) as w:
        for f, img in zip(forces, frames):
            w.write(img, float(f))
    return tmp_path


@pytest.mark.parametrize("case", ["few", "narrow", "shuffled"])
def test_cli_refuses_with_exit_2(case, aurova_dir, tmp_path, capsys):
    ds = AuthorsDataset(aurova_dir)
    samples = list(ds)
    frames = [s.frame for s in samples]
    forces = [s.force_n for s in samples]
    if case == "few":
        frames, forces = frames[:5], forces[:5]
    elif case == "narrow":
        forces = list(np.linspace(5.0, 6.0, len(frames)))
    else:
        forces = list(np.random.default_rng(0).permutation(forces))
    data = _dataset(tmp_path / "data", forces, frames)
    out = tmp_path / "out"
    rc = cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(data), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "refused" in err and "Traceback" not in err
    assert not out.exists()


def test_cli_refuses_missing_data_and_existing_out(calibrated, tmp_path, capsys):
    assert cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(tmp_path / "none"),
                     "--out", str(tmp_path / "o")]) == 2
    assert "folder not found" in capsys.readouterr().err
    before = json.loads((calibrated / "model.json").read_text())
    assert cli_main(["calibrate-force", str(default_bundle_path()), "--data", str(shared_data("aurova_digit_grasp")),
                     "--out", str(calibrated)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert json.loads((calibrated / "model.json").read_text()) == before


# -- depth bundles: fitted on the depth the runtime makes ------------------------------------
HOME = "aurova_background_b.png"  # the AUROVA unit untouched
PRESS = "1520.png"  # 11.88 N


def _as_recorded(aurova_dir, dest):
    """The AUROVA presses as ``record`` writes them: images and forces, no filt_img_depth/."""
    import shutil

    for sub in ("images", "forces"):
        shutil.copytree(aurova_dir / sub, dest / sub)
    assert not (dest / "filt_img_depth").exists()
    return dest


@pytest.mark.parametrize("variant", ["d", "rgbmod_d"])
def test_a_depth_bundle_is_fitted_on_the_depth_the_runtime_makes(variant, aurova_dir, tmp_path, capsys):
    """Presses without depth images are accepted; the fit's raw estimates are the runtime's, so the
    calibrated bundle reads on its own fit frames, through the runtime 'run' builds, exactly what
    the fitted map gives (the filt_img_depth fit read RE 0.156 through 'run' against 0.008 in the fit)."""
    from tactile_force.edge.data.metrics import readings_error
    from tactile_force.edge.reading import MAX_VALID_FORCE_N
    from tactile_force.edge.runtime.replay import replay_readings
    from tactile_force.edge.scene import shipped_bundles

    src = shipped_bundles()[variant]
    data = _as_recorded(aurova_dir, tmp_path / "presses")
    background = shared_data("digit_backgrounds", HOME)
    out = tmp_path / "cal"
    rc = cli_main(["calibrate-force", str(src), "--data", str(data), "--out", str(out), "--background",
                   str(background)])
    assert rc == 0, capsys.readouterr().err
    cal = load_bundle(out).manifest.force_calibration
    assert cal is not None and cal.frames == 11
    before = replay_readings(src, data, background)  # the source bundle as 'run' reads these presses
    raw = np.array([r.raw_force_n for r in before])
    truth = np.array([r.truth_n for r in before])
    assert np.all(np.isfinite(raw)) and len(raw) == 11
    run_error = readings_error(before)[0].overall  # what 'run' reports for these presses and this bundle
    assert cal.loo_before.re_mean == pytest.approx(run_error.re_mean, rel=1e-9)
    assert cal.loo_before.mae_mean == pytest.approx(run_error.mae_mean, rel=1e-9)
    assert truth.size == 11
    after = np.array([r.force_n for r in replay_readings(out, data, background)])
    fitted = np.clip(cal.apply(raw), 0.0, MAX_VALID_FORCE_N)
    np.testing.assert_allclose(after, fitted, atol=1e-4)


def test_calibrate_force_prints_the_error_run_prints_for_the_same_presses(aurova_dir, tmp_path, capsys):
    """The shipped D bundle on the AUROVA presses: calibrate-force's "before (raw)" line and run's
    "error vs truth" line are the same figures (both the readings of one replay path, clamped to
    [0, 15] N as every reading is; they read RE 0.343 and 0.307 when calibrate-force scored the
    unclamped raw estimates)."""
    import re

    from tactile_force.edge.scene import shipped_bundles

    src = shipped_bundles()["d"]
    background = shared_data("digit_backgrounds", HOME)
    rc = cli_main(["calibrate-force", str(src), "--data", str(aurova_dir), "--out", str(tmp_path / "cal"),
                   "--background", str(background)])
    out = capsys.readouterr().out
    assert rc == 0, out
    before = re.search(r"before \(raw\): RE ([0-9.]+) \+- ([0-9.]+), MAE ([0-9.]+)", out)
    rc = cli_main(["run", "--source", str(aurova_dir), "--bundle", str(src), "--background", str(background),
                   "--out", str(tmp_path / "readings.csv")])
    cap = capsys.readouterr()
    out = cap.out + cap.err
    assert rc == 0, out
    run = re.search(r"error vs truth over 11 CNN readings: RE ([0-9.]+) \+- ([0-9.]+), MAE ([0-9.]+)", out)
    assert before is not None and run is not None, out
    assert before.group(1, 2) == run.group(1, 2) and float(before.group(3)) == pytest.approx(float(run.group(3)),
                                                                                               abs=0.006)


def test_a_depth_bundle_without_a_no_contact_image_is_refused_when_the_presses_give_none(aurova_dir, tmp_path,
                                                                                      capsys):
    """The AUROVA grasp starts pressed: learnt from its first frames, the runtime's background holds a
    press and those frames give no force; too few are left, and the message says what to give."""
    from tactile_force.edge.scene import shipped_bundles

    out = tmp_path / "cal"
    rc = cli_main(["calibrate-force", str(shipped_bundles()["d"]), "--data", str(aurova_dir), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and "only 6 of the 11 presses" in err and "--background" in err and "Traceback" not in err, err
    assert not out.exists()


@pytest.mark.parametrize("variant", ["default", "d"])
def test_a_pressed_background_is_refused(variant, aurova_dir, tmp_path, capsys):
    """Checked as 'run' checks a given background: against the bundle's no-contact reference (the
    default bundle's data statistics), else against the lightest press (the d bundle has none)."""
    from tactile_force.edge.scene import shipped_bundles

    out = tmp_path / "cal"
    pressed = aurova_dir / "images" / PRESS
    rc = cli_main(["calibrate-force", str(shipped_bundles()[variant]), "--data", str(aurova_dir), "--out", str(out),
                   "--background", str(pressed)])
    err = capsys.readouterr().err
    assert rc == 2 and "refused" in err and "like a press" in err and str(pressed) in err, err
    assert not out.exists()
