"""``python -m benchmarks instructions``: callgrind's profile read right, the record's structure,
each mode counted alone in one run, and a runtime reading that executes at least what its bare
graph's call does.

Real valgrind, onnxruntime and OpenCV on the shipped default bundle, a few readings (callgrind
runs a program about 50x slower); skipped where valgrind is not installed or the host is not
x86-64 (the client requests). No timing assertions.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

import pytest
from tactile_force.benchmarks import instructions
from tactile_force.benchmarks.harness import callgrind, client_requests

needs_valgrind = pytest.mark.skipif(callgrind.valgrind() is None or not client_requests.SUPPORTED,
                                    reason="valgrind is not installed or the host is not x86-64: instruction counts "
                                           "need valgrind's callgrind and its client requests")


def test_parse_reads_self_costs_and_skips_inclusive_call_costs(tmp_path: Path) -> None:
    p = tmp_path / "callgrind.out"
    p.write_text("\n".join([
        "# callgrind format", "version: 1", "positions: line", "events: Ir", "summary: 170", "",
        "ob=(1) /usr/lib/libc.so.6", "fl=(1) ???", "fn=(1) __memset_avx2_unaligned_erms", "0 20", "",
        "ob=(2) /x/site-packages/cv2/cv2.abi3.so", "fl=(1)", "fn=(2) cv::resize", "0 100",
        "cob=(1)", "cfn=(1)", "calls=1 0", "0 20", "0 10", "",
        "ob=(3) /usr/bin/python3.11", "fl=(1)", "fn=(3) _PyEval_EvalFrameDefault", "0 40", ""]))
    prof = callgrind.parse(p)
    assert prof.total == 170
    assert sum(prof.by_function.values()) == 170  # the call's 20 (inclusive) is not counted twice
    g = prof.by_group()
    assert g["OpenCV"] == 110 and g["libc memset/memcpy"] == 20 and g["interpreter"] == 40
    assert set(g) == set(callgrind.GROUP_NAMES)


def test_without_valgrind_the_command_says_so_and_exits_0(monkeypatch, capsys, tmp_path: Path) -> None:
    monkeypatch.setattr(callgrind, "valgrind", lambda: None)
    args = argparse.Namespace(readings=1, quick=True, variants=None, before=None, out=tmp_path)
    assert instructions.run(args, ["instructions", "--quick"]) == 0
    assert "valgrind is not installed" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_without_client_requests_the_command_says_so_and_exits_0(monkeypatch, capsys, tmp_path: Path) -> None:
    monkeypatch.setattr(client_requests, "SUPPORTED", False)
    monkeypatch.setattr(callgrind, "valgrind", lambda: "/usr/bin/valgrind")
    args = argparse.Namespace(readings=1, quick=True, variants=None, before=None, out=tmp_path)
    assert instructions.run(args, ["instructions", "--quick"]) == 0
    assert "x86-64 only" in capsys.readouterr().err
    assert not list(tmp_path.iterdir())


def test_outside_valgrind_a_segment_counts_nothing_and_changes_nothing() -> None:
    if not client_requests.SUPPORTED:
        pytest.skip("the client requests are made on x86-64 only")
    assert not client_requests.on_valgrind()
    with client_requests.Segment("bare") as seg:
        x = sum(range(10))
    assert x == 45 and isinstance(seg, client_requests.Segment)
    with pytest.raises(ValueError, match="identifier"):
        client_requests.Segment("two words")


@needs_valgrind
def test_a_runtime_reading_counts_at_least_its_bare_call(tmp_path: Path) -> None:
    """Twenty readings of the default bundle, each mode (runtime, bare call, gate) counted alone in
    one run: the record is complete, each mode's count is its own (the gate is far less than the
    runtime, and its work is in OpenCV and the gate's kernels, not onnxruntime), and a reading
    executes at least what the bare graph's call does."""
    out = tmp_path / "out"
    proc = subprocess.run([sys.executable, "-m", "tactile_force.benchmarks", "instructions", "--readings", "20",
                           "--variants", "default", "--out", str(out)], capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr
    rec = json.loads((out / "instructions.json").read_text())
    for key in ("command", "commit", "cpu", "readings", "valgrind", "variants"):
        assert rec[key], key
    assert rec["readings"] == 20
    v, lean = rec["variants"]  # the compiled kernels, then the robot-side install's OpenCV path
    assert (v["label"], v["path"], lean["label"], lean["path"]) == ("RGBmod fast", "compiled",
                                                                      "RGBmod fast (OpenCV path)", "opencv")
    counts = v["counts"]
    assert {"runtime", "bare", "gate", "downscale", "downscale_opencv"} <= set(counts)
    for c in counts.values():
        assert set(c["groups"]) == set(callgrind.GROUP_NAMES)
    assert counts["bare"]["total"] > 1e5  # a graph call is work
    assert counts["runtime"]["total"] >= counts["bare"]["total"]
    assert counts["gate"]["groups"]["OpenCV"] > 0
    assert counts["gate"]["groups"]["onnxruntime"] == 0  # the gate's segment holds no model call
    assert counts["gate"]["total"] < 0.5 * counts["runtime"]["total"]
    assert 0 < counts["downscale"]["total"] < counts["gate"]["total"]  # a part of the gate step
    assert counts["downscale"]["groups"]["OpenCV"] == 0 < counts["downscale_opencv"]["groups"]["OpenCV"]
    assert counts["runtime"]["groups"]["onnxruntime"] >= 0.9 * counts["bare"]["groups"]["onnxruntime"]
    assert v["ratio"] == pytest.approx(counts["runtime"]["total"] / counts["bare"]["total"])
    # the robot-side path: its downscale is OpenCV's, its gate costs more than the kernels' (the same bare call)
    lc = lean["counts"]
    assert lc["downscale"]["groups"]["OpenCV"] > 0 and lc["gate"]["total"] > counts["gate"]["total"]
    assert lc["bare"]["total"] == pytest.approx(counts["bare"]["total"], rel=0.01)
    page = (out / "instructions.md").read_text()
    assert rec["cpu"] in page and rec["commit"] in page and "RGBmod" in page
    assert "The robot-side path against the compiled kernels" in page


def test_page_with_a_before_record_shows_the_goals_and_each_stage_before_and_after() -> None:
    g = dict.fromkeys(callgrind.GROUP_NAMES, 0.0)
    after = instructions.VariantCounts("default", "RGBmod", {"runtime": instructions.Count(4.2e6, g),
                                                               "bare": instructions.Count(3.7e6, g),
                                                               "gate": instructions.Count(0.4e6, g)}, 4.2 / 3.7)
    before = [{"bundle": "default", "label": "RGBmod", "setup": 1, "ratio": 5.2 / 3.7,
               "counts": {k: {"total": t, "groups": g} for k, t in (("runtime", 5.2e6), ("bare", 3.7e6),
                                                                     ("gate", 1.3e6))}}]
    rec = instructions.Record("python -m benchmarks instructions", "abc1234", "Some CPU", "a machine", 200, 16, 5,
                              "valgrind-3.19.0", [after], 1.0, "0000000", before, "a note on the counts")
    page = instructions.page(rec)
    assert "| RGBmod: runtime / bare graph <= 1.15x | 1.41x | 1.14x | met |" in page
    assert "| RGBmod | gate | 1.300 | 0.400 | -0.900 | -69 % |" in page
    assert "Some CPU" in page and "abc1234" in page and "0000000" in page and "a note on the counts" in page
    assert "What a goal leaves" not in page  # no downscale counted: no floors


def test_the_floors_compare_what_a_goal_leaves_with_what_the_checks_cost() -> None:
    g = dict.fromkeys(callgrind.GROUP_NAMES, 0.0)
    counts = {k: instructions.Count(t, g) for k, t in (("runtime", 4.6e6), ("bare", 4.0e6), ("gate", 0.5e6),
                                                         ("downscale", 0.2e6), ("downscale_opencv", 0.4e6))}
    v = instructions.VariantCounts("default", "RGBmod", counts, 4.6 / 4.0)
    rec = instructions.Record("cmd", "abc1234", "Some CPU", "a machine", 200, 16, 5, "valgrind-3.19.0", [v], 1.0)
    page = instructions.page(rec)
    # room 0.15 x 4.0 = 0.6; glue 4.6 - 4.0 - 0.5 = 0.1; left 0.6 - 0.2 - 0.1 = 0.3; checks 0.5 - 0.2 = 0.3
    assert ("| RGBmod | 1.15x | 0.600 | 0.200 (OpenCV's x2 steps: 0.400) | 0.100 | 0.300 | 0.300 | 1.0x |"
            in page)
