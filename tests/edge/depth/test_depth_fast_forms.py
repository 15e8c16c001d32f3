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
