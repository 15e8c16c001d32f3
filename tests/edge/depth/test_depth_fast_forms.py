"""The depth stage's per-frame shortcuts give exactly what their plain forms give (the compact
depth bundles were trained on the stage's depth, so a shortcut may not move a single value):
midpoint slopes by in-place ufuncs == the 1 x 2 correlation, masking by multiply == boolean
assignment, the saturation count with its pre-check and reused buffers == a plain count."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge.depth import DepthOptions, DepthStage
from tactile_force.edge.depth.depth_image import exact_depth_image
from tactile_force.edge.depth.stage import _midpoint_slopes

MAPPING = "edge/assets/virtual_digit_depth.npz"


@pytest.mark.parametrize("seed", range(5))
def test_midpoint_slopes_equal_the_correlation(seed):
    rng = np.random.default_rng(seed)
    gx = (rng.standard_normal((80, 60)) * 10 ** rng.uniform(-3, 3, (80, 60))).astype(np.float32)
    gy = (rng.standard_normal((80, 60)) * 10 ** rng.uniform(-3, 3, (80, 60))).astype(np.float32)
    gx[rng.random((80, 60)) < 0.5] = 0.0  # zero outside a contact, as the stage fills them
    want_x = cv2.filter2D(gx, -1, np.array([[0.5, 0.5]], np.float32), anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
    want_y = cv2.filter2D(gy, -1, np.array([[0.5], [0.5]], np.float32), anchor=(0, 0),
                          borderType=cv2.BORDER_CONSTANT)
    _midpoint_slopes(gx, gy)
    assert np.array_equal(gx, want_x) and np.array_equal(gy, want_y)


def test_depth_image_masking_by_multiply_equals_boolean_assignment():
    rng = np.random.default_rng(1)
    height = (rng.standard_normal((80, 60)) * 30).astype(np.float32)  # negative, in range and above 255 levels
    mask = rng.random((80, 60)) > 0.4
    out = np.empty((80, 60, 1), np.uint8)
    exact_depth_image(height, mask, 255 / 48, out)
    scaled = np.clip(height * np.float32(255 / 48), 0, 255)
    scaled[~mask] = 0
    assert np.array_equal(out[..., 0], np.rint(scaled).astype(np.uint8))
    assert out[..., 0][~mask].max() == 0 and out.max() == 255


def _plain_saturated(frame: np.ndarray, mask: np.ndarray) -> int:
    return int(((frame == 255).any(axis=2) & (mask > 0)).sum())


def test_saturated_count_equals_a_plain_count_with_and_without_255_values():
    stage = DepthStage(DepthOptions(mapping=MAPPING, downscale=4))
    rng = np.random.default_rng(2)
    for i in range(12):
        frame = rng.integers(0, 255, (80, 60, 3), dtype=np.uint8)  # no 255: the pre-check answers
        if i % 2:
            frame[rng.random((80, 60)) < 0.2, i % 3] = 255
        mask = rng.random((80, 60)) > 0.5
        contact = int(mask.sum())
        assert stage._saturated_px(frame, mask, contact) == _plain_saturated(frame, mask)
    full = rng.integers(0, 256, (320, 240, 3), dtype=np.uint8)  # another shape: its own buffers
    mask = rng.random((320, 240)) > 0.5
    assert stage._saturated_px(full, mask, int(mask.sum())) == _plain_saturated(full, mask)
    view = full[::4, ::4]  # not contiguous: no pre-check, still counted
    m = mask[::4, ::4]
    assert stage._saturated_px(view, m, int(m.sum())) == _plain_saturated(view, m)


def _plain_lut_depth(stage: DepthStage, frame: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """The LUT path of the depth stage on its grid in its plain form: every pixel's cell, its
    guarded gradients where the mask is, midpoint slopes, the solve, the depth image."""
    lut = stage.lut
    assert lut is not None
    q = (frame.astype(np.float32) - stage._bg_box) * np.float32(1.0 / lut.bin_width)
    qi = np.floor(np.clip(q, 0, lut.bins - 1)).astype(np.intp)
    g = stage._glut[(qi[..., 0] * lut.bins + qi[..., 1]) * lut.bins + qi[..., 2]]
    m = mask > 0
    gx, gy = np.where(m, g[..., 0], 0).astype(np.float32), np.where(m, g[..., 1], 0).astype(np.float32)
    _midpoint_slopes(gx, gy)
    h = stage.solver.solve(gx, gy)
    scaled = np.clip(h * np.float32(stage.options.levels_per_px), 0, 255)
    scaled[~m] = 0
    return np.rint(scaled).astype(np.uint8)[..., None]


def test_lut_depth_on_the_grid_equals_its_plain_form_frame_after_frame():
    """The stage's LUT path (cells in one transform, the mask as 0/1 floats, buffers reused
    from frame to frame) gives the plain form's depth image exactly, for masks that move."""
    stage = DepthStage(DepthOptions(mapping=MAPPING, downscale=4))
    rng = np.random.default_rng(3)
    lut = stage.lut
    assert lut is not None
    half = lut.bins * lut.bin_width / 2.0
    for i in range(8):
        frame = np.clip(stage._bg_box + half + rng.normal(0, half / 2, (80, 60, 3)), 0, 255).astype(np.uint8)
        mask = np.zeros((80, 60), np.uint8)
        y, x = rng.integers(0, 60), rng.integers(0, 40)
        mask[y:y + rng.integers(5, 20), x:x + rng.integers(5, 20)] = 255
        mask[rng.random((80, 60)) < 0.05] = 0  # holes
        res = stage.process(frame, mask, checked=True)
        assert res.ok, res.detail
        assert np.array_equal(res.depth, _plain_lut_depth(stage, frame, mask)), i
