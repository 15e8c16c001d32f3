"""The footprint benchmark counts the distinct cache lines a reading touches, each stage alone, under
callgrind's cache simulator: the counts are those of what ran (a gate reads the whole frame; a reading
touches at least what its bare graph call does), and the page says what they are."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from tactile_force.benchmarks import footprint
from tactile_force.benchmarks.harness import callgrind, client_requests

needs_valgrind = pytest.mark.skipif(callgrind.valgrind() is None or not client_requests.SUPPORTED,
                                    reason="needs valgrind's callgrind and x86-64 (client requests)")


def test_totals_read_the_events_of_a_dump(tmp_path: Path) -> None:
    p = tmp_path / "d.out"
    p.write_text("events: Ir Dr Dw I1mr D1mr D1mw ILmr DLmr DLmw\nfl=x\n0 1 2 3\nsummary: 100 5 6 7 8 9 10 11 12\n")
    assert footprint._totals(p) == {"Ir": 100, "Dr": 5, "Dw": 6, "I1mr": 7, "D1mr": 8, "D1mw": 9, "ILmr": 10,
                                    "DLmr": 11, "DLmw": 12}


@needs_valgrind
def test_a_reading_touches_its_frame_and_at_least_its_bare_call(tmp_path: Path) -> None:
    out = tmp_path / "out"
    p = subprocess.run([sys.executable, "-m", "tactile_force.benchmarks", "footprint", "--quick", "--variants", "default",
                        "--paths", "opencv", "--out", str(out)], capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr
    rec = json.loads((out / "footprint.json").read_text())
    (v,) = rec["variants"]
    modes = v["modes"]
    frame_lines = 320 * 240 * 3 // 64  # the gate reduces the whole frame: every line of it is read
    assert modes["gate"]["data_lines"] >= frame_lines
    assert modes["runtime"]["data_lines"] >= modes["bare"]["data_lines"] > 0
    assert modes["runtime"]["code_lines"] >= modes["bare"]["code_lines"] > 100
    assert modes["runtime"]["instructions"] > modes["gate"]["instructions"] > 0
    page = (out / "footprint.md").read_text()
    assert "distinct lines of code" in page and rec["cpu"] in page and "RGBmod fast (OpenCV path)" in page
