"""Exposure checks on real frames: usable frames pass, unusable ones are named."""

from __future__ import annotations

import cv2
import numpy as np
from tactile_force.edge.frames import exposure_problem

from tests.conftest import shared_data


def _real_frames():
    paths = sorted(shared_data("aurova_digit_grasp", "images").glob("*.png"))
    paths += sorted(shared_data("digit_backgrounds").iterdir())
    return [(p.name, cv2.imread(str(p))) for p in paths]


def test_real_frames_are_usable():
    for name, frame in _real_frames():
        assert exposure_problem(frame) is None, name


def test_unusable_versions_of_real_frames_are_named():
    _, frame = _real_frames()[0]
    bright = np.clip(frame.astype(np.float32) * 4.0, 0, 255).astype(np.uint8)  # LEDs far too bright
    assert exposure_problem(bright) == "over-exposed"
    assert exposure_problem((frame // 40).astype(np.uint8)) == "all-dark"
    assert exposure_problem(np.full_like(frame, 252)) == "all-white"
    # A bright but unclipped frame is still usable.
    assert exposure_problem(np.clip(frame.astype(np.int16) + 40, 0, 255).astype(np.uint8)) is None
