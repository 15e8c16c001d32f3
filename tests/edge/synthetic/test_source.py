"""VirtualDigitSource: grasp sequences at 60 fps with ground truth, lead-in and LED drift."""

from __future__ import annotations

import numpy as np
import pytest
from tactile_force.edge import FrameSource, TimedFrame
from tactile_force.edge.synthetic import PHASES, VirtualDigitSource


@pytest.fixture(scope="module")
def frames() -> list[TimedFrame]:
    with VirtualDigitSource(seed=4, n_grasps=2, fps=60.0, start_ns=1_000) as src:
        assert isinstance(src, FrameSource)
        out = list(src)
        assert src.read() is None and src.stats.frames == len(out)
    return out


def test_timing_and_indices(frames):
    ts = np.array([f.timestamp_ns for f in frames])
    assert ts[0] == 1_000 and np.all(np.diff(ts) > 0)
    assert np.allclose(np.diff(ts), 1e9 / 60.0, atol=1)
    assert [f.index for f in frames] == list(range(len(frames)))
    assert all(f.frame.shape == (320, 240, 3) and f.frame.dtype == np.uint8 for f in frames)


def test_starts_without_contact_then_grasps(frames):
    lead = [f for f in frames[:60]]
    assert all(f.truth_n == 0.0 and f.meta["phase"] == "no_contact" for f in lead)
    for g in (0, 1):
        phases = [f.meta["phase"] for f in frames if f.meta["grasp"] == g]
        # phases appear in grasp order: approach, ramp, hold, release, no contact
        order = [PHASES.index(p) for p in phases]
        assert order == sorted(order) and set(phases) == set(PHASES)
        forces = np.array([f.truth_n for f in frames if f.meta["grasp"] == g])
        ramp = np.array([f.truth_n for f in frames if f.meta["grasp"] == g and f.meta["phase"] == "ramp"])
        assert np.all(np.diff(ramp) > 0) and forces.max() >= 3.0
    touching = [f for f in frames if f.truth_n > 0]
    assert all("indenter" in f.meta and "stiffness" in f.meta for f in touching)


def test_contact_frames_differ_from_background_and_leds_drift(frames):
    empty = np.stack([f.frame for f in frames if f.truth_n == 0.0]).astype(np.float32)
    hold = [f for f in frames if f.meta["phase"] == "hold"]
    base = empty[:60].mean(0)
    assert np.abs(hold[0].frame - base).mean() > 2 * np.abs(empty[1] - base).mean()
    brightness = empty.mean(axis=(1, 2, 3))
    assert brightness.max() - brightness.min() > 0.5  # slow LED drift over the stream


def test_same_seed_same_stream():
    a = [f.frame for f in VirtualDigitSource(seed=9, n_grasps=1, start_ns=0)][::25]
    b = [f.frame for f in VirtualDigitSource(seed=9, n_grasps=1, start_ns=0)][::25]
    assert all(np.array_equal(x, y) for x, y in zip(a, b))


def test_bad_arguments():
    with pytest.raises(ValueError, match="n_grasps"):
        VirtualDigitSource(n_grasps=0)
