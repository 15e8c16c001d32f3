"""Frames: check_frame accepts exactly the contract; the exposure check sees every pixel."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from tactile_force.edge.frames import exposure_problem

from benchmarks.robustness import Outcome, exposure_patterns, frame_inputs, probe_exposure, probe_frame

from .conftest import ROBUST


@ROBUST
@given(frame_inputs())
def test_check_frame_accepts_the_contract_and_names_everything_else(x):
    v = probe_frame(x)
    assert v.ok, v


@ROBUST
@given(exposure_patterns())
def test_exposure_verdict_matches_the_whole_frame(frame):
    v = probe_exposure(frame)
    assert v.ok, v


def test_checkerboard_is_not_all_white():
    """9ed225d sampled every 4th pixel: a 0/255 checkerboard (mean 127.5) read as all-white."""
    r, c = np.indices((320, 240))
    board = np.where(((r + c) % 2 == 0)[..., None], 255, 0).astype(np.uint8).repeat(3, axis=2)
    assert exposure_problem(board) is None
    assert probe_exposure(board).outcome is Outcome.ACCEPTED
    stripes = np.where((r % 4 == 0)[..., None], 255, 0).astype(np.uint8).repeat(3, axis=2)  # mean 63.75
    assert exposure_problem(stripes) is None
