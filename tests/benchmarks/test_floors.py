"""benchmarks/floors.py: the check-less gate counts what it should, the OpenCV call counter
counts and restores, and the floor arithmetic follows the measurements (fake timings; no
wall-clock assertions)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from benchmarks import floors
from benchmarks.machine import MachineState


def test_check_less_gate_counts_changed_pixels_of_the_reduced_frame():
    rng = np.random.default_rng(0)
    frame = rng.integers(40, 200, (320, 240, 3), dtype=np.uint8)
    from tactile_force.edge.gate.reduce import default_reduction, reduce_frames

    bg = reduce_frames(frame[None], default_reduction(4))[0]
    gate = floors.CheckLessGate(bg, frame.shape, threshold=10.0)
    assert gate(frame) == 0
    pressed = frame.copy()
    pressed[40:80, 20:60, 1] = np.clip(pressed[40:80, 20:60, 1].astype(int) + 60, 0, 255).astype(np.uint8)
    small = reduce_frames(pressed[None], default_reduction(4))[0]
    expected = int((np.abs(small.astype(int) - bg.astype(int)).max(axis=2) > 10).sum())
    assert gate(pressed) == expected and 90 <= expected <= 100  # the 10 x 10 reduced block
    with pytest.raises(ValueError, match="expected"):
        floors.CheckLessGate(np.ascontiguousarray(bg[:, :30]), frame.shape)


def test_counting_opencv_counts_calls_and_restores_the_module():
    a = np.zeros((8, 8), np.uint8)
    before = cv2.countNonZero
    with floors.counting_opencv() as counts:
        cv2.countNonZero(a)
        cv2.countNonZero(a)
        cv2.GaussianBlur(a, (3, 3), 0)
    assert counts["countNonZero"] == 2 and counts["GaussianBlur"] == 1
    assert cv2.countNonZero is before


def test_gate_opencv_calls_are_those_of_the_shipped_gate_per_frame():
    from benchmarks.frames import FramePool

    rng = np.random.default_rng(1)
    bg = rng.integers(60, 120, (320, 240, 3), dtype=np.uint8)
    frames = np.stack([bg] * 8)
    frames[:, 100:160, 80:140] = 200  # a press on every frame
    pool = FramePool(frames, np.zeros((8, 1, 1), np.float32), np.ones(8, np.float32), np.stack([bg] * 2), [])
    calls = floors.gate_opencv_calls(pool, frames=4)
    assert calls["resize"] >= 2  # the one downscale: two exact 2x2 steps
    assert calls["findContours"] == 1  # the blobs of the contact
    assert sum(calls.values()) > 10


def _run(**p50_us: float) -> dict:
    run: dict = {k: np.full(10, v, float) for k, v in p50_us.items()}
    run["machine"] = MachineState(0.0, 0.0, 0.0, 0.0, 0.0, 1.0, False)
    return run


def test_floor_rows_sum_the_unavoidable_pieces():
    run = _run(**{"reference bare": 400.0, "read frame": 6.0, "shrink": 40.0, "shrink nearest": 8.0,
                  "numba shrink": np.nan, "check-less gate": 60.0, "gate reduce": 40.0, "gate checks": 120.0,
                  "gate plain": 80.0, "shipped gate": 160.0, "network bare": 240.0, "network 1/8 bare": 200.0,
                  "runtime total": 450.0, "runtime gate": 180.0, "runtime glue": 30.0})
    rows, goals = floors.floor_rows(run)
    assert rows[0][3] == pytest.approx(1.0) and len(rows) == 14  # the numba row has no samples: left out
    gate, checks, total, eighth, eighth_checks = goals
    assert gate[2] == pytest.approx(60 / 400) and gate[5] == "NO"  # 0.15 > 0.12
    assert checks[2] == pytest.approx((8 + 120) / 400) and checks[5] == "NO"
    assert gate[4] == pytest.approx(160 / 400)  # the shipped gate of this run beside the floor
    assert total[2] == pytest.approx((240 + 30 + 60) / 400) and total[5] == "NO"  # 0.825
    assert eighth[2] == pytest.approx((200 + 30 + 60) / 400) and eighth[5] == "yes"  # 0.725
    assert eighth_checks[2] == pytest.approx((200 + 30 + 8 + 120) / 400) and eighth_checks[5] == "NO"
    cheap = _run(**{"reference bare": 400.0, "read frame": 6.0, "shrink": 20.0, "shrink nearest": 8.0,
                    "numba shrink": 30.0, "check-less gate": 40.0, "gate reduce": 20.0, "gate checks": 20.0,
                    "gate plain": 15.0, "shipped gate": 40.0, "network bare": 200.0, "network 1/8 bare": np.nan,
                    "runtime total": 300.0, "runtime gate": 40.0, "runtime glue": 20.0})
    rows, goals = floors.floor_rows(cheap)
    assert [g[5] for g in goals] == ["yes", "yes", "yes"]  # no width-1/8 rows without their samples
    assert len(rows) == 14


def test_numba_shrink_gives_the_shipped_reduction_when_numba_is_there():
    shrink = floors.numba_shrink()
    if shrink is None:
        pytest.skip("numba is not installed (an optional experiment of the floors page, not a dependency)")
    from tactile_force.edge.gate.reduce import default_reduction, reduce_frames

    frame = np.random.default_rng(2).integers(0, 256, (320, 240, 3), dtype=np.uint8)
    out = np.empty((80, 60, 3), np.uint8)
    shrink(frame, out)
    assert np.array_equal(out, reduce_frames(frame[None], default_reduction(4))[0])
