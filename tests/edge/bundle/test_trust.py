"""Honest readings on real sensors, through the public API: ContactGate +
ForceRuntime + the embedded default bundle, on the shared real frames.

The truth of every adversarial frame below is "no contact or cannot be judged": a reading
with a finite force and none of the judging flags would be a silent wrong force.
"""

from __future__ import annotations

import logging
import math

import cv2
import numpy as np
import pytest
from tactile_force.edge import (
    ContactGate,
    Flags,
    ForceRuntime,
    GateOptions,
    RuntimeOptions,
    Sensor,
)
from tactile_force.edge.bundle.data_stats import DataStats, DataStatsCheck
from tactile_force.edge.fitting.data_stats import compute_data_stats

from tests.conftest import ListSource, shared_data

JUDGING = (Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.BACKGROUND_MISMATCH | Flags.OUT_OF_DISTRIBUTION
           | Flags.SATURATED)
HOME = "aurova_background_b.png"  # the AUROVA unit and session (the grasp's, and the bundle's training background)


def _unit(name: str) -> np.ndarray:
    return cv2.imread(str(shared_data("digit_backgrounds", name)))


def _aurova(aurova_dir) -> list[tuple[np.ndarray, float]]:
    paths = sorted((aurova_dir / "images").glob("*.png"), key=lambda p: int(p.stem))
    return [(cv2.imread(str(p)), float((aurova_dir / "forces" / f"force_{p.stem}.txt").read_text().split()[0]))
            for p in paths]


@pytest.fixture(scope="module")
def stats() -> DataStats:
    """data_stats of 160 frames drawn like the default bundle's training set (virtual DIGIT)."""
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions
    from tactile_force.edge.synthetic.indenters import paper_indenter_names
    from tactile_force.edge.synthetic.sampling import led_gain, sample_contact

    digit = VirtualDigit(VirtualDigitOptions(seed=5))
    rng = np.random.default_rng(5)
    names = paper_indenter_names()
    frames = [digit.render(sample_contact(rng, names[i % len(names)]), float(rng.uniform(1.0, 20.0)),
                           led_gain=led_gain(rng)).frame for i in range(160)]
    return compute_data_stats(frames, digit.background, source="test: 160 virtual frames")


@pytest.fixture(scope="module")
def model(stats):
    from tactile_force.edge import OnnxForceModel
    from tactile_force.edge.scene import default_bundle_path

    m = OnnxForceModel(default_bundle_path())
    m.bundle.manifest.data_stats = stats
    return m


def _run(model, frames, background, truth=None, options: GateOptions | None = None, origin: str = ""):
    gate = ContactGate(options)
    if background is not None:
        gate.capture_background([background] if isinstance(background, np.ndarray) else background, origin=origin)
    rt = ForceRuntime([Sensor("s", ListSource(frames, truth), gate)], model, RuntimeOptions(deadline_ms=1e9))
    out: list = []
    rt.run(on_reading=out.append)
    return out, gate, rt


def _silent(readings) -> list:
    return [r for r in readings if math.isfinite(r.force_n) and not (r.flags & JUDGING)]


# -- the gate at the model's resolution ----------------------------------------------------------
def test_gate_works_at_80x60_and_makes_the_full_mask_only_when_asked(aurova_dir):
    bg = _unit(HOME)
    frame = cv2.imread(str(aurova_dir / "images" / "1510.png"))
    gate = ContactGate()  # default: x4, the 80x60 the compact model sees
    assert gate.options.downscale == 4
    gate.capture_background([bg])
    r = gate.update(frame)
    assert r.contact and r.thumb is not None and r.thumb.shape == (20, 15, 3)
    assert not r.mask_computed  # an RGBmod reading never pays for the upscale
    area, centroid = r.area_px, r.centroid  # geometry comes from the small mask
    assert not r.mask_computed
    mask = r.mask
    assert r.mask_computed and mask.shape == (320, 240) and set(np.unique(mask)) <= {0, 255}
    # What it should be: every 4x4 block constant (nearest-neighbour upscale of the 80x60
    # mask), the same area and centroid as reported before it existed.
    blocks = mask.reshape(80, 4, 60, 4)
    assert (blocks == blocks[:, :1, :, :1]).all()
    assert int(np.count_nonzero(mask)) == area
    ys, xs = np.nonzero(mask)
    assert centroid == pytest.approx((xs.mean(), ys.mean()), abs=1e-6)


def test_full_mask_is_exact_when_the_factor_does_not_divide_the_frame():
    rng = np.random.default_rng(0)
    bg = rng.integers(90, 110, (322, 242, 3), dtype=np.uint8)
    frame = bg.copy()
    cv2.circle(frame, (120, 160), 40, (200, 60, 60), -1)
    gate = ContactGate()
    gate.capture_background([bg])
    r = gate.update(frame)
    assert r.contact and r.mask.shape == (322, 242)
    assert int(np.count_nonzero(r.mask)) == r.area_px


# -- adversarial frames through the runtime ------------------------------------------------------
def _adversarial(bg: np.ndarray) -> dict[str, list[np.ndarray]]:
    rng = np.random.default_rng(1)
    h, w = bg.shape[:2]
    band = bg.copy()
    band[100:140] = rng.integers(0, 256, band[100:140].shape, dtype=np.uint8)
    dark = bg.copy()
    dark[:80] = (dark[:80] * 0.15).astype(np.uint8)
    hsv = cv2.cvtColor(bg, cv2.COLOR_BGR2HSV)
    hsv[..., 0] = ((hsv[..., 0].astype(np.int16) + 10) % 180).astype(np.uint8)
    return {
        "grey": [np.full_like(bg, v) for v in (100, 128, 180)],
        "gain": [np.clip(bg * g, 0, 255).astype(np.uint8) for g in (0.7, 0.8, 1.2, 1.3)],
        "shift": [cv2.warpAffine(bg, np.float32([[1, 0, d], [0, 1, d / 2]]), (w, h), borderMode=cv2.BORDER_REFLECT)
                  for d in (5, 10, 20)],
        "rotation": [cv2.warpAffine(bg, cv2.getRotationMatrix2D((w / 2, h / 2), a, 1.0), (w, h),
                                    borderMode=cv2.BORDER_REFLECT) for a in (2, 5, 10)],
        "rgb": [bg[..., ::-1].copy()],
        "defocus": [cv2.GaussianBlur(bg, (0, 0), s) for s in (3, 6)],
        "occlusion": [dark],
        "hue": [cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)],
        "noise": [np.clip(bg + rng.normal(0, 50, bg.shape), 0, 255).astype(np.uint8), band],
    }


@pytest.mark.parametrize("category", ["grey", "gain", "shift", "rotation", "rgb", "defocus", "occlusion", "hue",
                                      "noise"])
def test_no_silent_force_on_adversarial_frames(model, category):
    bg = _unit(HOME)
    for frame in _adversarial(bg)[category]:
        readings, _, _ = _run(model, [frame, frame], bg)
        assert not _silent(readings), f"{category}: {[(r.force_n, r.flags.names(), r.detail) for r in readings]}"


def test_another_unit_and_the_other_finger_give_background_mismatch_and_nan(model):
    bg = _unit(HOME)
    for name in ("fots_digit_bg.png", "tacto_bg_digit_240_320.jpg", "aurova_background_a.png"):
        other = _unit(name)
        for frame in (other, other[:, ::-1].copy()):
            readings, _, rt = _run(model, [frame], bg)
            (r,) = readings
            assert r.flags & Flags.BACKGROUND_MISMATCH and math.isnan(r.force_n), (name, r)
            assert "background mismatch" in r.detail and "re-learnt" in r.detail
            assert rt.stats.background_mismatch == 1 and rt.stats.inferred == 0  # the CNN did not run


def test_rgb_order_is_invalid_input_naming_the_colour_order(model, aurova_dir):
    bg = _unit(HOME)
    frames = [f[..., ::-1].copy() for f, _ in _aurova(aurova_dir)[::3]] + [bg[..., ::-1].copy()]
    readings, _, _ = _run(model, frames, bg)
    assert not _silent(readings)
    assert all(r.flags & Flags.INVALID_INPUT and "colour order" in r.detail for r in readings), \
        [(r.flags.names(), r.detail[:60]) for r in readings]


def test_uniform_and_noisy_frames_are_invalid_input(model):
    bg = _unit(HOME)
    for frame, word in ((np.full_like(bg, 128), "uniform"),
                        (np.clip(bg + np.random.default_rng(2).normal(0, 50, bg.shape), 0, 255).astype(np.uint8),
                         "noise")):
        (r,), _, _ = _run(model, [frame], bg)
        assert r.flags & Flags.INVALID_INPUT and word in r.detail and math.isnan(r.force_n)


def test_moved_gel_names_the_motion(model):
    bg = _unit(HOME)
    h, w = bg.shape[:2]
    frame = cv2.warpAffine(bg, cv2.getRotationMatrix2D((w / 2, h / 2), 3, 1.0), (w, h), borderMode=cv2.BORDER_REFLECT)
    (r,), _, _ = _run(model, [frame], bg)
    assert r.flags & Flags.BACKGROUND_MISMATCH and "moved" in r.detail


# -- recovery policy -----------------------------------------------------------------------------
def test_led_step_is_flagged_then_the_background_is_relearnt(model, aurova_dir, caplog):
    bg = _unit(HOME)
    dim = np.clip(bg * 0.8, 0, 255).astype(np.uint8)
    press = np.clip(cv2.imread(str(aurova_dir / "images" / "1510.png")) * 0.8, 0, 255).astype(np.uint8)
    opts = GateOptions(relearn_frames=10)
    with caplog.at_level(logging.INFO, logger="tactile_force.edge.gate.contact_gate"):
        readings, gate, _ = _run(model, [dim] * 14 + [press] * 3, bg, options=opts)
    flags = [r.flags for r in readings]
    assert all(f & Flags.BACKGROUND_MISMATCH for f in flags[:10]), [f.names() for f in flags[:12]]
    assert gate.relearned == 1 and "re-learnt" in caplog.text and "sudden brightness step" in caplog.text
    assert all(f & Flags.NO_CONTACT for f in flags[10:14])  # the step became the background
    assert all(not (f & JUDGING & ~Flags.SATURATED) and math.isfinite(r.force_n)
               for f, r in zip(flags[14:], readings[14:]))  # a press against it is served again


def test_a_long_press_during_a_step_is_never_absorbed(model, aurova_dir):
    bg = _unit(HOME)
    press = np.clip(cv2.imread(str(aurova_dir / "images" / "1512.png")) * 0.8, 0, 255).astype(np.uint8)
    readings, gate, _ = _run(model, [press] * 60, bg, options=GateOptions(relearn_frames=10))
    assert gate.relearned == 0
    assert all(r.flags & Flags.BACKGROUND_MISMATCH and math.isnan(r.force_n) for r in readings)


def test_another_unit_plugged_in_is_relearnt_once_stable(model, caplog):
    other = _unit("tacto_bg_digit_240_320.jpg")
    with caplog.at_level(logging.WARNING, logger="tactile_force.edge.gate.contact_gate"):
        readings, gate, _ = _run(model, [other] * 15, _unit(HOME), options=GateOptions(relearn_frames=10))
    flags = [r.flags for r in readings]
    assert all(f & Flags.BACKGROUND_MISMATCH for f in flags[:10]) and gate.relearned == 1
    assert all(f == Flags.NO_CONTACT for f in flags[10:]) and gate.state == "ok"
    assert caplog.text.count("background mismatch") == 1 and "re-learnt" in caplog.text


def test_mismatch_clears_when_the_frame_fits_again(model):
    bg = _unit(HOME)
    other = _unit("fots_digit_bg.png")
    readings, gate, _ = _run(model, [other, other, bg, bg], bg)
    assert [bool(r.flags & Flags.BACKGROUND_MISMATCH) for r in readings] == [True, True, False, False]
    assert readings[-1].flags & Flags.NO_CONTACT and gate.state == "ok"


def test_a_given_background_is_checked_against_the_first_live_frames(model):
    readings, gate, _ = _run(model, [_unit(HOME)], _unit("tacto_bg_digit_240_320.jpg"), origin="scene bg.png")
    (r,) = readings
    assert r.flags & Flags.BACKGROUND_MISMATCH
    assert "background given at start (scene bg.png) does not fit the live frames" in r.detail
    assert gate.state.startswith("mismatch")


def test_slow_led_drift_is_followed_without_flags(model):
    bg = _unit(HOME)
    frames = [np.clip(bg * (1.0 + 0.002 * k), 0, 255).astype(np.uint8) for k in range(120)]  # +24 % in 2 s
    readings, _, _ = _run(model, frames, bg)
    assert all(r.flags == Flags.NO_CONTACT for r in readings), {tuple(r.flags.names()) for r in readings}


# -- real contact: no false alarms ---------------------------------------------------------------
def test_every_real_aurova_frame_reads_contact_without_alarms(model, aurova_dir):
    data = _aurova(aurova_dir)
    readings, _, _ = _run(model, [f for f, _ in data], _unit(HOME), truth=[x for _, x in data])
    alarms = Flags.INVALID_INPUT | Flags.BACKGROUND_MISMATCH | Flags.OUT_OF_DISTRIBUTION | Flags.NO_CONTACT
    assert all(not (r.flags & alarms) and math.isfinite(r.force_n) for r in readings), \
        [(r.truth_n, r.flags.names(), r.detail) for r in readings if r.flags & alarms]


def test_virtual_grasps_have_at_most_one_percent_false_alarms(model):
    from tactile_force.edge.synthetic import VirtualDigitSource

    src = VirtualDigitSource(seed=11, n_grasps=3, peak_n=(2.0, 20.0))
    gate = ContactGate()
    rt = ForceRuntime([Sensor("v", src, gate)], model, RuntimeOptions(deadline_ms=1e9))
    out: list = []
    rt.run(on_reading=out.append)
    contact = [r for r in out if r.truth_n is not None and r.truth_n >= 1.0]
    alarms = [r for r in contact if r.flags & (Flags.INVALID_INPUT | Flags.BACKGROUND_MISMATCH |
                                               Flags.OUT_OF_DISTRIBUTION)]
    assert len(contact) > 100
    assert len(alarms) <= 0.01 * len(contact), [(r.truth_n, r.flags.names(), r.detail) for r in alarms[:5]]


# -- another sensor type: GelSight Wedge frames on the DIGIT bundle -------------------------------
def _wedge(video) -> list[np.ndarray]:
    from benchmarks.harness.data import wedge_frames

    return wedge_frames(video)


def test_gelsight_wedge_frames_never_give_a_silent_force(model):
    videos = sorted(shared_data("gelsight_wedge_grasps", "example_data").glob("*/*.avi"))
    assert len(videos) >= 20
    for video in videos[::5]:
        frames = _wedge(video)
        readings, _, _ = _run(model, frames[1:], frames[0])
        assert not _silent(readings), (video.name, [(r.force_n, r.flags.names()) for r in _silent(readings)][:3])
        assert any(r.flags & Flags.OUT_OF_DISTRIBUTION for r in readings)  # the contact frames are flagged


# -- data_stats ----------------------------------------------------------------------------------
def test_data_stats_fields_and_validation(stats):
    assert stats.frames == 160 and 0 < stats.contact_frames <= 160
    assert (stats.thumb_rows, stats.thumb_cols) == (20, 15) and len(stats.cell_lo) == 20 * 15 * 3
    assert all(lo <= hi for lo, hi in zip(stats.cell_lo, stats.cell_hi))
    assert 0 < stats.contact_area_frac_max < 1 and stats.deformation_max > 0
    bad = DataStats(**{**stats.__dict__, "cell_hi": stats.cell_hi[:10]})
    with pytest.raises(ValueError, match="cell_hi: 10 values"):
        bad.check()


def test_data_stats_travel_in_the_manifest(stats):
    from tactile_force.edge.typed_json import from_json, to_json

    back = from_json(DataStats, to_json(stats), "data_stats")
    assert back == stats
    with pytest.raises(ValueError, match="data_stats.cell_lo"):
        from_json(DataStats, {**to_json(stats), "cell_lo": "abc"}, "data_stats")


def test_saturated_when_the_contact_exceeds_the_data(model, stats, aurova_dir):
    firm = cv2.imread(str(aurova_dir / "images" / "1512.png"))
    small = DataStats(**{**stats.__dict__, "contact_area_frac_max": 0.05})
    model.bundle.manifest.data_stats = small
    try:
        (r,), _, _ = _run(model, [firm], _unit(HOME))
    finally:
        model.bundle.manifest.data_stats = stats
    assert r.flags & Flags.SATURATED and "exceeds the largest in the bundle's data" in r.detail
    assert math.isfinite(r.force_n)


def test_without_data_stats_the_check_is_skipped_with_one_warning(caplog):
    with caplog.at_level(logging.WARNING, logger="tactile_force.edge.bundle.data_stats"):
        chk = DataStatsCheck(None, "old-bundle")
    assert not chk.active and chk.out_of_distribution(np.zeros((20, 15, 3), np.uint8)) == ""
    assert caplog.text.count("no data_stats") == 1 and "old-bundle" in caplog.text


def test_data_stats_written_into_a_bundle_are_used_by_the_runtime(stats, tmp_path):
    from tactile_force.edge import OnnxForceModel
    from tactile_force.edge.bundle.store import load_bundle, write_bundle
    from tactile_force.edge.scene import default_bundle_path

    src = load_bundle(default_bundle_path())
    src.manifest.data_stats = stats
    write_bundle(tmp_path / "b", src.onnx_path.read_bytes(), src.manifest)
    m = OnnxForceModel(tmp_path / "b")
    assert m.bundle.manifest.data_stats == stats
    video = sorted(shared_data("gelsight_wedge_grasps", "example_data").glob("*/golf_ball_1.avi"))[0]
    frames = _wedge(video)
    readings, _, _ = _run(m, frames[1:], frames[0])
    assert any(r.flags & Flags.OUT_OF_DISTRIBUTION and "outside what the bundle's data covered" in r.detail
               for r in readings)

