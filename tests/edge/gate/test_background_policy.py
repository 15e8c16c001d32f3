"""edge/gate/learning.py on its own: entering and clearing a mismatch (one warning, one
note), and when a mismatched background is due to be re-learnt (stable, blob-free frames per
kind, relearn_frames = 0 never). Real GateOptions and thumbnails as the gate makes them."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from tactile_force.edge.gate.learning import RelearnPolicy
from tactile_force.edge.gate.options import GateOptions

THUMB = np.full((20, 15, 3), 100, np.uint8)
ALL_FIT = np.full((20, 15), 255, np.uint8)
BORDERS_BAD = ALL_FIT.copy()
BORDERS_BAD[:2] = BORDERS_BAD[-2:] = BORDERS_BAD[:, :2] = BORDERS_BAD[:, -2:] = 0


def _due_after(p: RelearnPolicy, frames: int, kind: str, frac: float = 0.0, inliers: np.ndarray = ALL_FIT) -> int:
    """Frames until due (0 = not within ``frames``)."""
    for i in range(1, frames + 1):
        if p.due(THUMB, frac, kind, inliers):
            return i
    return 0


def test_enter_warns_once_and_clear_notes_it(caplog):
    p = RelearnPolicy(GateOptions(relearn_frames=4))
    with caplog.at_level(logging.INFO, logger="tactile_force.edge.gate.contact_gate"):
        p.enter("sudden brightness step", "photometric")
        p.enter("sudden brightness step of 30", "photometric")
        assert (p.reason, p.kind) == ("sudden brightness step of 30", "photometric")
        p.clear()
        p.clear()
    msgs = [r.getMessage() for r in caplog.records]
    assert sum("background mismatch: sudden brightness step;" in m for m in msgs) == 1
    assert "re-learnt after 4 stable frames" in msgs[0]
    assert sum("mismatch cleared" in m for m in msgs) == 1
    assert (p.reason, p.kind, p.stable) == ("", "", 0)


def test_photometric_step_is_due_after_relearn_frames_stable_blob_free_frames():
    p = RelearnPolicy(GateOptions(relearn_frames=5))
    p.enter("step", "photometric")
    # the first frame has nothing to compare with: 1 + 5 frames
    assert _due_after(p, 10, "photometric") == 6


def test_a_blob_or_an_unstable_frame_restarts_the_count():
    o = GateOptions(relearn_frames=3)
    p = RelearnPolicy(o)
    p.enter("step", "photometric")
    assert not p.due(THUMB, 0.0, "photometric", ALL_FIT)
    assert not p.due(THUMB, 0.0, "photometric", ALL_FIT) and p.stable == 1
    assert not p.due(THUMB, o.off_area_frac * 2, "photometric", ALL_FIT) and p.stable == 0  # a press left
    assert not p.due(THUMB + 20, 0.0, "photometric", ALL_FIT) and p.stable == 0  # the frame changed
    assert _due_after(p, 10, "photometric") == 4  # the change back is one more unstable frame


def test_global_change_needs_the_borders_motion_does_not():
    p = RelearnPolicy(GateOptions(relearn_frames=3))
    p.enter("another unit", "global")
    assert _due_after(p, 10, "global", inliers=ALL_FIT) == 0  # a press in the middle: never absorbed
    p.clear()
    p.enter("another unit", "global")
    assert _due_after(p, 10, "global", inliers=BORDERS_BAD) == 4
    p.clear()
    p.enter("moved", "motion")
    assert _due_after(p, 10, "motion", inliers=ALL_FIT) == 4


def test_relearn_frames_zero_is_never_due():
    p = RelearnPolicy(GateOptions(relearn_frames=0))
    p.enter("step", "photometric")
    assert _due_after(p, 50, "photometric") == 0 and p.stable == 49  # counted, never acted on


def test_learner_averages_the_kept_frames_as_float32_copies():
    from tactile_force.edge.gate.learning import BackgroundLearner

    learn = BackgroundLearner()
    work = np.full((80, 60, 3), 10, np.uint8)
    thumb = np.full((20, 15, 3), 30, np.uint8)
    assert learn.add(work, thumb, 1.0) == 1
    work[:] = 21  # the gate reuses its buffers: the learner keeps copies
    thumb[:] = 41
    assert learn.add(work, thumb, 2.0) == 2
    bg, th, noise = learn.mean()
    assert bg.dtype == np.float32 and bg.shape == (80, 60, 3) and th.shape == (20, 15, 3)
    assert float(bg[0, 0, 0]) == 15.5 and float(th[0, 0, 0]) == 35.5 and noise == 1.5
    learn.clear()
    assert learn.add(work, thumb, 4.0) == 1 and learn.mean()[2] == 4.0


def test_gate_learns_from_the_first_background_frames_live():
    from tactile_force.edge.gate.contact_gate import ContactGate

    g = ContactGate(GateOptions(background_frames=3))
    frames = [np.full((320, 240, 3), v, np.uint8) for v in (90, 100, 110)]
    for f in frames[:2]:
        assert not g.update(f).background_ready
    g.update(frames[2])
    assert g.background_ready and g._bg is not None and float(g._bg[0, 0, 0]) == 100.0


def test_refresh_blends_a_frame_in_and_renews_the_reference():
    from tactile_force.edge.gate.checks import Reference
    from tactile_force.edge.gate.learning import refresh

    bg = np.full((80, 60, 3), 100.0, np.float32)
    bg_thumb = np.full((20, 15, 3), 100.0, np.float32)
    ref = Reference(bg_thumb)
    dark = ref.dark()
    refresh(bg, bg_thumb, np.full((80, 60, 3), 150, np.uint8), np.full((20, 15, 3), 150, np.uint8), 0.1, ref)
    assert float(bg[0, 0, 0]) == pytest.approx(105.0) and float(bg_thumb[0, 0, 0]) == pytest.approx(105.0)
    assert ref.dark() is not dark and float(ref.dark()[0, 0, 0]) == pytest.approx(0.45 * 105.0 + 2.0)
