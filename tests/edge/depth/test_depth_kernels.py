"""The depth stage's compiled kernels (edge/depth/kernels.py) give the numpy chain's results bit for
bit: depth images, heights (compared as float32 bit patterns), ok / detail / contact pixels, on
virtual-DIGIT contact frames, real AUROVA frames through the contact gate, and made-up masks and
frames (edges of the grid, saturation, empty masks, read-only arrays); tests/edge/depth/oracle.py
holds the numpy chain."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge import ContactGate, load_bundle, shipped_bundles
from tactile_force.edge.depth import DepthOptions, DepthStage
from tactile_force.edge.frames import TimedFrame
from tactile_force.edge.runtime import build_depth_stage
from tactile_force.edge.runtime.gating import GateStep

from tests.conftest import compiled_kernels, shared_data
from tests.edge.depth.oracle import oracle_depth

MAPPING = "edge/assets/virtual_digit_depth.npz"


@pytest.fixture(autouse=True, scope="module")
def _kernels():
    compiled_kernels("gate", "depth")


def _stage(name: str = "d") -> DepthStage:
    return build_depth_stage(None, load_bundle(shipped_bundles()[name]).manifest)


def _same(stage: DepthStage, frame: np.ndarray, mask: np.ndarray, checked: bool = True) -> bool:
    """The stage's result equals the oracle's, bit for bit; returns whether it was ok."""
    got = stage.process(frame, mask, checked=checked)
    want = oracle_depth(stage, np.ascontiguousarray(frame), np.ascontiguousarray(mask))
    assert (got.ok, got.detail, got.contact_px) == (want.ok, want.detail, want.contact_px)
    assert got.depth.dtype == np.uint8 and np.array_equal(got.depth, want.depth)
    if want.ok:
        assert got.height is not None and want.height is not None
        assert np.array_equal(got.height.view(np.uint32), want.height.view(np.uint32))
    return want.ok


def _gated(frames, background):
    """(reduced image, reduced mask) of each frame the contact gate finds in contact."""
    gate = ContactGate()
    gate.capture_background(background)
    step = GateStep("s", gate)
    out = []
    for i, f in enumerate(frames):
        g = step.run(TimedFrame(f, i, i, arrival_ns=i))
        if g is not None and g.contact and g.reduced is not None:
            out.append((g.reduced.copy(), g.reduced_mask.copy()))
    return out


@pytest.mark.parametrize("name", ["d", "rgbmod_d"])
def test_shipped_depth_bundles_use_the_kernels(name):
    assert _stage(name)._uses_kernels and _stage(name)._kernels is not None  # not the numpy path


def test_full_resolution_and_float64_stay_on_numpy():
    assert DepthStage(DepthOptions(mapping=MAPPING))._uses_kernels is False
    assert DepthStage(DepthOptions(mapping=MAPPING, downscale=4, solver_dtype="float64"))._uses_kernels is False


def test_virtual_contact_frames_equal_the_numpy_chain():
    from tactile_force.benchmarks.bench import contact_frames

    pool = contact_frames(24, seed=3)
    pairs = _gated(pool.rgb, pool.background)
    assert len(pairs) >= 20
    stage = _stage()
    assert all(_same(stage, f, m) for f, m in pairs)
    # the same stage, frames in another order (no state carried from frame to frame)
    assert all(_same(stage, f, m) for f, m in pairs[::-1])


def test_real_aurova_frames_equal_the_numpy_chain(aurova_dir):
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    paths = sorted((aurova_dir / "images").glob("*.png"), key=lambda p: int(p.stem))
    pairs = _gated([cv2.imread(str(p)) for p in paths], [bg])
    assert len(pairs) == len(paths) == 11
    stage = _stage("rgbmod_d")
    assert all(_same(stage, f, m) for f, m in pairs)


def test_made_up_masks_and_frames_equal_the_numpy_chain():
    """Masks touching every edge of the grid, single pixels, full masks, noise frames (colour
    differences beyond the LUT's span: both clamps), frames with channels at 255."""
    stage = _stage()
    h, w = stage._grid_hw
    rng = np.random.default_rng(0)
    oks = 0
    for trial in range(60):
        frame = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)
        if trial % 3 == 0:  # near the background: cells in the middle of the LUT
            bg = stage._bg_box + np.float32(stage.lut.bins * stage.lut.bin_width / 2.0)
            frame = np.clip(bg + rng.normal(0, 12, bg.shape), 0, 255).astype(np.uint8)
        mask = np.zeros((h, w), np.uint8)
        r0, c0 = rng.integers(0, h), rng.integers(0, w)
        r1, c1 = rng.integers(r0, h + 1), rng.integers(c0, w + 1)
        mask[r0:r1, c0:c1] = 255
        mask[rng.random((h, w)) < 0.05] = 255 if trial % 2 else 0
        if trial == 1:
            mask[:] = 255
        if trial == 2:
            mask[:] = 0
            mask[h - 1, w - 1] = 255
        if trial == 4:
            mask[:] = 0
            mask[0, 0] = 255
        oks += _same(stage, frame, mask)
    assert oks > 30


def test_empty_and_saturated_masks():
    stage = _stage()
    h, w = stage._grid_hw
    frame = np.full((h, w, 3), 128, np.uint8)
    mask = np.zeros((h, w), np.uint8)
    assert not _same(stage, frame, mask)  # empty mask
    mask[10:20, 10:20] = 255
    frame[10:20, 10:16, 1] = 255  # 60 of 100 contact pixels with a channel at 255
    res = stage.process(frame, mask, checked=True)
    assert not res.ok and res.detail == "saturated: 60/100 contact pixels at 255"
    assert not _same(stage, frame, mask)
    frame[10:20, 14:16, 1] = 128  # 40 of 100: below half
    assert _same(stage, frame, mask)


def test_read_only_inputs_and_other_mask_types_give_the_same_depth():
    from tactile_force.benchmarks.bench import contact_frames

    pool = contact_frames(4, seed=5)
    stage = _stage()
    for f, m in _gated(pool.rgb, pool.background):
        want = oracle_depth(stage, f, m)
        fr, mr = f.copy(), m.copy()
        fr.setflags(write=False)
        mr.setflags(write=False)
        assert _same(stage, fr, mr, checked=False)
        for other in (m > 0, np.asfortranarray(m)):  # the numpy path: same depth
            assert np.array_equal(stage.process(f, other).depth, want.depth)
