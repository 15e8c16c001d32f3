"""edge/gate/checks.py on its own: each judging check answers on thumbnails built to show (or
not show) what it looks for, and writes only into the buffers it is given. Real OpenCV; the
thumbnails are the gate's own (ContactGate's 20x15 thumbnail of a real DIGIT background)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge.gate.checks import (
    Reference,
    borders_changed,
    colour_swapped,
    dark_share,
    is_uniform,
    motion_explained,
)
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.sources import load_background

from tests.conftest import shared_data


@pytest.fixture(scope="module")
def bg() -> np.ndarray:
    return load_background(shared_data("digit_backgrounds", "aurova_background_b.png"))[0]


def _thumb(frame: np.ndarray) -> np.ndarray:
    g = ContactGate()
    g.capture_background([frame])
    assert g._bg_thumb is not None
    return g._bg_thumb.copy()  # 20 x 15 x 3 float32


def test_dark_share_counts_cells_dark_on_every_channel(bg):
    t = _thumb(bg)
    ref = Reference(t)
    cmp_buf, dark_buf = np.empty(t.shape, np.uint8), np.empty(t.shape[:2], np.uint8)
    assert dark_share(t, ref.dark(), cmp_buf, dark_buf) == 0.0
    covered = t.copy()
    covered[:5] = 0.0  # a quarter of the rows blacked out
    assert dark_share(covered, ref.dark(), cmp_buf, dark_buf) == pytest.approx(0.25)
    one_channel = t.copy()
    one_channel[:5, :, 0] = 0.0  # dark on B only: a colour shift, not occlusion
    assert dark_share(one_channel, ref.dark(), cmp_buf, dark_buf) == 0.0


def test_colour_swapped_finds_rgb_order(bg):
    t = _thumb(bg)
    x = t.reshape(-1, 3)
    swapped = np.ascontiguousarray(t[..., ::-1]).reshape(-1, 3)
    assert colour_swapped(swapped, x, 8.0, fit_frac=0.1)
    assert not colour_swapped(x.copy(), x, 8.0, fit_frac=1.0)  # as it is it fits already


def test_motion_explained_high_for_a_shift_low_for_a_local_press(bg):
    t = _thumb(bg)
    ref = Reference(t)
    res = np.empty_like(t)
    moved = cv2.warpAffine(bg, np.float32([[1, 0, 6], [0, 1, 0]]), (bg.shape[1], bg.shape[0]),
                           borderMode=cv2.BORDER_REPLICATE)  # the gel moved 6 px sideways
    shifted = _thumb(moved)
    assert motion_explained(shifted, t, res, ref) > 0.35
    np.testing.assert_array_equal(res, shifted - t)  # the residual is left in the buffer
    pressed = t.copy()
    pressed[8:12, 6:9] += 40.0
    assert motion_explained(pressed, t, res, ref) < 0.35
    assert motion_explained(t.copy(), t, res, ref) == 0.0  # nothing to explain


def test_reference_makes_its_dark_level_and_motion_basis_again_after_refresh(bg):
    t = _thumb(bg)
    ref = Reference(t)
    dark, motion = ref.dark(), ref.motion()
    assert ref.dark() is dark and ref.motion() is motion  # cached
    t *= 0.5  # the gate refreshes its background thumbnail in place
    ref.refreshed()
    np.testing.assert_allclose(ref.dark(), 0.45 * t + 2.0, rtol=1e-6)
    assert ref.motion() is not motion


def test_borders_changed_counts_the_strips_that_mostly_do_not_fit():
    inl = np.full((20, 15), 255, np.uint8)
    assert borders_changed(inl) == 0
    inl[:2] = 0  # the top strip
    assert borders_changed(inl) == 1
    inl[:, :2] = 0
    inl[:, -2:] = 0
    inl[-2:] = 0
    assert borders_changed(inl) == 4
    centre = np.full((20, 15), 255, np.uint8)
    centre[5:15, 4:11] = 0  # a press in the middle touches no border
    assert borders_changed(centre) == 0


def test_is_uniform(bg):
    assert not is_uniform(_thumb(bg))
    assert is_uniform(np.full((20, 15, 3), 90.0, np.float32))
    flat = np.full((20, 15, 3), 90.0, np.float32)
    flat[0, 0, 1] = 200.0  # one cell far off: a spread of ~6 grey levels
    assert not is_uniform(flat)


def test_noise_verdict_burst_blur_and_fine():
    from tactile_force.edge.gate.checks import noise_verdict

    assert noise_verdict(2.0, 2.0, [1.0, 1.0, 1.0], 2.2) == (False, "")
    burst, why = noise_verdict(9.0, 2.0, [1.0, 1.0, 1.0], 2.2)  # > 2.2 x 2 + 1
    assert burst and why.startswith("noise burst: pixel noise 9.0 grey levels against 2.0")
    assert noise_verdict(9.0, 2.0, [2.0, 1.0, 1.0], 2.2) == (False, "")  # a brighter frame is noisier
    burst, why = noise_verdict(0.5, 2.0, [1.0, 1.0, 1.0], 2.2)  # < 45 % of the background's detail
    assert not burst and why.startswith("blurred frame: fine detail 0.5 grey levels against 2.0")
    assert noise_verdict(0.5, 2.0, [0.5, 1.0, 1.0], 2.2) == (False, "")  # a darker frame has less detail
