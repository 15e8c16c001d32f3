"""The bench's statistics: one definition of "too few readings" (MIN_P99_READINGS) in the code
and on both docs pages, judged on the readings at the cadence; ``missed`` never counts the
warm-up frames, so the readings and the missed frames add up to ``--cadence-frames``."""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
import pytest
from tactile_force.benchmarks.bench import REPORT_JSON, read_report
from tactile_force.benchmarks.harness.stats import MIN_P99_READINGS
from tactile_force.edge.cli import main
from tactile_force.edge.scene import default_bundle_path

DOCS = Path(__file__).resolve().parents[2] / "docs"


def test_a_late_reader_misses_no_warm_up_frame():
    from benchmarks.harness.sources import PacedMemorySource

    src = PacedMemorySource(np.zeros((2, 320, 240, 3), np.uint8), fps=1000.0, n=200, count_from=20)
    assert src.read().index == 0
    time.sleep(0.04)  # 40 frame periods: the reader is late past the 20 warm-up frames
    b = src.read()
    assert b.index >= 40
    assert src.stats.dropped == b.index - 1  # every skipped frame
    assert src.missed == b.index - 20  # the skipped frames from the first measured one on


@pytest.mark.parametrize("fps, cadence_frames", [(10_000.0, 100), (200.0, 120)])
def test_readings_and_missed_add_up_to_the_cadence_frames_and_too_few_is_one_rule(tmp_path, fps, cadence_frames):
    out = tmp_path / "b"
    rc = main(["bench", "--bundle", str(default_bundle_path()), "--frames", "99", "--fps", str(fps),
               "--cadence-frames", str(cadence_frames), "--repeats", "1", "--budget-ms", "1000", "--out", str(out)])
    b = read_report(out / REPORT_JSON).bundles[0]
    assert b.cadence is not None
    assert b.cadence.total_ms.n + b.cadence.missed == cadence_frames, (b.cadence.total_ms.n, b.cadence.missed)
    few = b.cadence.total_ms.n < MIN_P99_READINGS
    assert (b.verdict == "TOO_FEW_READINGS") == few, (b.verdict, b.cadence.total_ms.n)
    assert rc == (1 if few else 0)  # --frames 99 back to back is not judged


def test_one_floor_in_the_code_and_on_both_pages():
    from benchmarks import robustness_verbs

    assert robustness_verbs.FLOOR is MIN_P99_READINGS
    bench, robustness = (DOCS / "bench.md").read_text(), (DOCS / "robustness.md").read_text()
    assert re.search(rf"fewer than {MIN_P99_READINGS} readings\s+\(`MIN_P99_READINGS`", bench)
    assert f"`MIN_P99_READINGS` = {MIN_P99_READINGS}" in robustness
    assert "--cadence-frames N" in robustness  # the readings bench judges
    assert "`--frames 99` with the default 300 cadence readings" in bench
