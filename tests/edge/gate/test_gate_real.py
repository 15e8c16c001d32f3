"""Contact gate on real sensor data (../shared/data), plus hysteresis and refresh.

References used (see docs/runtime.md):
- DIGIT backgrounds: each file is one frame of a unit; the two AUROVA backgrounds are from
  different sessions with changed illumination (they differ by up to ~87 grey levels), so
  no other real frame is a fair same-session reference. The reference is the frame itself
  as the camera would deliver it again: 5 noisy captures (Gaussian sensor noise sigma 2)
  averaged, tested against an independent noisy capture, also with +-3 % LED gain drift.
- AUROVA grasp frames: aurova_background_b.png, the no-contact frame of the same unit and
  session (median difference 5 grey levels away from the contact).
- GelSight Mini presses: the dataset's own no-contact frame f0.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge import FrameError
from tactile_force.edge.gate import ContactGate, GateOptions

from tests.conftest import shared_data

GELSIGHT_MINI = GateOptions.gelsight_mini()  # threshold 28 + convex hulls (larger halo than DIGIT)


def _noisy(img: np.ndarray, rng: np.random.Generator, gain: float = 1.0, sigma: float = 2.0) -> np.ndarray:
    x = img.astype(np.float32) * gain + rng.normal(0.0, sigma, img.shape)
    return np.clip(x, 0, 255).astype(np.uint8)


def _digit_backgrounds():
    folder = shared_data("digit_backgrounds")
    files = sorted(p for p in folder.iterdir() if p.suffix in (".png", ".jpg"))
    assert len(files) >= 4
    return files


@pytest.mark.parametrize("downscale", [1, 2, 4])
def test_every_real_digit_background_reads_no_contact(downscale):
    rng = np.random.default_rng(0)
    for path in _digit_backgrounds():
        img = cv2.imread(str(path))
        assert img.shape == (320, 240, 3), path
        gate = ContactGate(GateOptions(downscale=downscale))
        gate.capture_background([_noisy(img, rng) for _ in range(5)])
        for gain in (1.0, 1.03, 0.97):
            r = gate.update(_noisy(img, rng, gain))
            assert not r.contact, f"{path.name} (gain {gain}) read as contact, area {r.area_px} px"
            assert not r.saturation_seen
            assert not r.mismatch and not r.invalid, (path.name, gain, r)


@pytest.mark.parametrize("downscale", [1, 2, 4])
def test_every_real_aurova_frame_reads_contact(aurova_dir, downscale):
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    frames = sorted((aurova_dir / "images").glob("*.png"), key=lambda p: int(p.stem))
    assert len(frames) == 11
    areas = []
    for path in frames:
        gate = ContactGate(GateOptions(downscale=downscale))
        gate.capture_background([bg])
        r = gate.update(cv2.imread(str(path)))
        assert r.contact, f"{path.name} read as no contact (area {r.area_px} px)"
        assert not r.mismatch and not r.invalid, (path.name, r)
        assert r.mask.shape == (320, 240) and r.mask.dtype == np.uint8
        assert set(np.unique(r.mask)) <= {0, 255}
        assert r.area_px == int(np.count_nonzero(r.mask))
        x, y = r.centroid
        assert 60 < x < 200 and 60 < y < 200  # the round indenter sits mid-gel
        assert not r.saturation_seen  # 11.9 N is inside the valid range
        areas.append(r.area_px)
    # Contact grows with force: the 11.9 N frames have far more area than the 1.08 N one.
    assert areas[-1] > 5 * areas[0]


def test_same_unit_other_session_is_not_a_fair_reference():
    """Documents why the backgrounds are not cross-referenced: aurova a vs b (different
    sessions) differ so much that the gate (correctly) sees a change."""
    a = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_a.png")))
    b = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    gate = ContactGate()
    gate.capture_background([b])
    assert gate.update(a).area_px > 0


def _gelsight_ious(options: GateOptions) -> np.ndarray:
    z = np.load(shared_data("gelsight_mini_ball_presses.npz"))
    f0, imgs, centers, radii = z["f0"], z["imgs"], z["touch_center"], z["touch_radius"]
    yy, xx = np.mgrid[: f0.shape[0], : f0.shape[1]]
    ious = []
    for img, (cx, cy), r in zip(imgs, centers.astype(float), radii.astype(float)):
        gate = ContactGate(options)
        gate.capture_background([f0])
        res = gate.update(img)
        assert res.contact and res.mask.shape == f0.shape[:2]
        label = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
        m = res.mask > 0
        ious.append((m & label).sum() / (m | label).sum())
    return np.array(ious)


def test_gelsight_mini_mask_matches_labelled_circles():
    ious = _gelsight_ious(GELSIGHT_MINI)
    print(f"GelSight Mini IoU mean {ious.mean():.3f} min {ious.min():.3f} over {ious.size} presses")
    # Measured mean 0.652, min 0.582 (downscale 2; full res 0.653 / 0.587). Before (threshold
    # 25, no hulls): 0.615 / 0.541. The mask still holds part of the deformed gel ring around
    # the ball (outside the labelled circle) and the labels' centres sit up to ~18 px from the
    # mask's; the aim of 0.7 is not met (see docs/runtime.md, "Contact gate").
    assert ious.mean() >= 0.64
    assert ious.min() >= 0.56


def test_convex_hull_makes_gelsight_masks_convex_and_closer_to_the_labels():
    with_hull = _gelsight_ious(GELSIGHT_MINI)
    without = _gelsight_ious(GateOptions.gelsight_mini(convex_hull=False))
    # Measured 0.652 vs 0.617 mean at the same threshold.
    assert with_hull.mean() > without.mean() + 0.02
    z = np.load(shared_data("gelsight_mini_ball_presses.npz"))

    def hull_ratio(options: GateOptions) -> float:
        gate = ContactGate(options)
        gate.capture_background([z["f0"]])
        mask = gate.update(z["imgs"][3]).mask
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        hull = np.zeros_like(mask)
        cv2.drawContours(hull, [cv2.convexHull(c) for c in contours], -1, 255, cv2.FILLED)
        return np.count_nonzero(hull) / np.count_nonzero(mask)

    # Full resolution (no upscaling staircase): the hull mask is convex, the plain one is not.
    assert hull_ratio(GateOptions.gelsight_mini(downscale=1)) < 1.02  # measured 1.011 (rasterisation)
    assert hull_ratio(GateOptions.gelsight_mini(downscale=1, convex_hull=False)) > 1.05  # measured 1.09


def test_convex_hull_is_off_by_default_and_must_be_a_bool():
    assert GateOptions().convex_hull is False
    with pytest.raises(ValueError, match="convex_hull"):
        ContactGate(GateOptions(convex_hull="yes"))


def test_downscaled_mask_agrees_with_full_resolution(aurova_dir):
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    ious = []
    for path in sorted((aurova_dir / "images").glob("*.png")):
        img = cv2.imread(str(path))
        masks = []
        for ds in (1, 2):
            g = ContactGate(GateOptions(downscale=ds))
            g.capture_background([bg])
            masks.append(g.update(img).mask > 0)
        ious.append((masks[0] & masks[1]).sum() / (masks[0] | masks[1]).sum())
    # Measured: 0.73 on the two faint (1-2 N) patches of ~1300 px, >= 0.88 above.
    assert np.mean(ious) > 0.85 and min(ious) > 0.65, np.round(ious, 2)


def test_hysteresis_and_background_learning(aurova_dir):
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    light = cv2.imread(str(aurova_dir / "images" / "1500.png"))  # 1.08 N: ~1.7 % of the frame
    firm = cv2.imread(str(aurova_dir / "images" / "1512.png"))  # 10.6 N: ~40 %
    # On at 5 %, off below 1 %: the light touch sits between the two thresholds.
    gate = ContactGate(GateOptions(background_frames=3, on_area_frac=0.05, off_area_frac=0.01, refresh_rate=0.0))
    for _ in range(3):
        r = gate.update(bg)
        assert not r.background_ready and not r.contact
    assert gate.background_ready
    seq = [(light, False), (firm, True), (light, True), (bg, False), (light, False)]
    for k, (frame, want) in enumerate(seq):
        r = gate.update(frame)
        assert r.contact is want, f"step {k}: contact {r.contact}, area {r.area_px} px"


def test_background_refresh_follows_slow_drift():
    img = cv2.imread(str(_digit_backgrounds()[0]))
    gate = ContactGate(GateOptions(refresh_rate=0.1))
    gate.capture_background([img])
    # LED drift of 40 grey levels in red on the top half only (global compensation removes
    # just the mean shift), reached slowly over 100 frames.
    drifted = img.astype(np.int16)
    for step in range(1, 101):
        f = drifted.copy()
        f[:160, :, 2] += int(round(step * 0.4))
        r = gate.update(np.clip(f, 0, 255).astype(np.uint8))
        assert not r.contact, f"slow drift read as contact at step {step}"
    frozen = ContactGate(GateOptions(refresh_rate=0.0))
    frozen.capture_background([img])
    f = drifted.copy()
    f[:160, :, 2] += 40
    assert frozen.update(np.clip(f, 0, 255).astype(np.uint8)).contact  # without refresh it trips


def test_gate_rejects_bad_frames():
    gate = ContactGate()
    with pytest.raises(FrameError, match="empty"):
        gate.update(np.zeros((0, 240, 3), np.uint8))
    with pytest.raises(FrameError, match="dtype float32"):
        gate.update(np.full((320, 240, 3), np.nan, np.float32))
    with pytest.raises(FrameError, match="no frames"):
        gate.capture_background([])
    gate.capture_background([np.full((320, 240, 3), 100, np.uint8)])
    with pytest.raises(FrameError, match="background is"):
        gate.update(np.full((480, 640, 3), 100, np.uint8))
    with pytest.raises(ValueError, match="blur"):
        ContactGate(GateOptions(blur=4))
    with pytest.raises(ValueError, match="off_area_frac"):
        ContactGate(GateOptions(on_area_frac=0.001, off_area_frac=0.01))
