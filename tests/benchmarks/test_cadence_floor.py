"""The cadence page's floor: the one downscale then the bare call, fed what the runtime feeds the
network, and the table of ms added to the reference."""

from __future__ import annotations

import numpy as np
from tactile_force.edge import ContactGate

from benchmarks.cadence import ADDED_GOALS, DownscaleThenBare, Phase, Round, floor_table, setup


def test_the_floor_feeds_the_network_the_gates_reduced_image():
    pool, bare, model = setup()
    try:
        floor = DownscaleThenBare(bare, pool)
        gate = ContactGate()
        gate.capture_background(pool.background)
        for i in range(3):
            floor(i)
            want = gate.reduce(pool.rgb[i])
            np.testing.assert_array_equal(floor.feed[floor.name][0], want)
            assert np.shares_memory(floor.feed[floor.name], floor.work.small)  # the buffer made once
        assert floor.path in ("compiled kernel", "OpenCV")
    finally:
        model.close()


def _phase(ms: float) -> Phase:
    t = np.full(100, ms)
    return Phase([t], {}, 1.0, 1.0, 100)


def test_floor_table_gives_ms_added_to_the_reference_per_percentile():
    ref = np.linspace(0.4, 0.6, 101)  # p50 0.5, p99 0.598
    rds = [Round(ref, {"1 sensor, before": _phase(0.9), "1 sensor, after": _phase(0.8)}, ref + 0.2)]
    text = floor_table(rds)
    lines = text.splitlines()
    p50 = next(line for line in lines if line.startswith("| p50"))
    p99 = next(line for line in lines if line.startswith("| p99"))
    assert f"<= {ADDED_GOALS[50]:g}" in p50 and "+0.200" in p50 and "0 of 1" in p50  # 0.2 > 0.15
    assert "+0.400" in p50 and "+0.300" in p50  # 0.9 - 0.5, 0.8 - 0.5
    assert "+0.200" in p99 and "1 of 1" in p99  # 0.2 <= 0.25
