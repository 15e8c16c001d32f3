"""Quick tests of the benchmark harness logic (percentiles, tables, the --check verdict,
per-stage arithmetic) with injected fake timings; no wall-clock assertions."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import benchmarks.__main__ as cli
from benchmarks import check
from benchmarks.bundles import ModelConfig, parse_config
from benchmarks.latency import LatencyCase, LatencyResult, measure
from benchmarks.machine import MachineState
from benchmarks.stats import Percentiles, fmt, markdown_table, percentiles


def test_percentiles_of_known_sample_and_nan_handling():
    p = percentiles(np.arange(1, 101, dtype=float).tolist() + [math.nan])
    assert p.n == 100
    assert p.p50 == pytest.approx(50.5)
    assert p.p90 == pytest.approx(90.1)
    assert p.p99 == pytest.approx(99.01)
    assert math.isnan(percentiles([]).p50) and percentiles([math.inf]).n == 0


def test_markdown_table_formats_and_rejects_ragged_rows():
    t = markdown_table(["a", "b", "c"], [[1, 0.12345, None], ["x", math.nan, 2.5]], digits=2)
    lines = t.splitlines()
    assert lines[0] == "| a | b | c |" and lines[1] == "|---|---|---|"
    assert lines[2] == "| 1 | 0.12 | - |" and lines[3] == "| x | - | 2.50 |"
    with pytest.raises(ValueError, match="row 0 has 2 cells"):
        markdown_table(["a", "b", "c"], [[1, 2]])
    assert fmt(3) == "3" and fmt("s") == "s"


def test_config_names_round_trip():
    for c in (ModelConfig("rgbmod", 0.25, 4), ModelConfig("rgbmod+d", 1.0, 1), ModelConfig("dmod", 0.125, 8)):
        assert parse_config(c.name) == c
    with pytest.raises(ValueError, match="VARIANT-wWIDTH-sK"):
        parse_config("resnet")


def _result(case: LatencyCase, gate: float, inference: float, depth: float = math.nan) -> LatencyResult:
    def p(v: float) -> Percentiles:
        return Percentiles(v, v, v, v, 100) if not math.isnan(v) else Percentiles(v, v, v, v, 0)

    total = gate + inference + (0 if math.isnan(depth) else depth)
    return LatencyResult(case, {"source": p(0.1), "gate": p(gate), "depth": p(depth), "inference": p(inference),
                                "total": p(total), "gate+inference": p(gate + inference), "glue": p(0.0)}, gmacs=0.1)


def _fake_measure(gate_ms: float, inference_ms: float):
    def fake(case: LatencyCase) -> LatencyResult:
        if case.engine == "torch-eager":
            return _result(case, 0.2, 80.0)
        d = 2.5 if case.needs_depth else math.nan
        return _result(case, gate_ms, inference_ms, d)

    return fake


class FakeWindow:
    """Machine watcher stand-in: each window reports the next of ``busy`` (True = busy)."""

    def __init__(self, busy: list[bool]):
        self.busy, self.made = list(busy), 0

    def __call__(self):
        busy = self.busy[min(self.made, len(self.busy) - 1)]
        self.made += 1
        state = MachineState(4.5 if busy else 0.1, 4.5 if busy else 0.1, 2600.0, 2600.0, 0.8 if busy else 0.01,
                             5.0, busy)

        class W:
            def stop(self_inner):
                return state

        return W()


@pytest.fixture
def no_bundle_build(monkeypatch, tmp_path):
    monkeypatch.setattr(check, "rgbmod_candidates", lambda: [(tmp_path, "fake bundle", 0.07)])
    monkeypatch.setattr(check, "trained_int8", lambda variant, cfg: None)


def _run(measure_fn, busy=(False,), repeats=3):
    window = FakeWindow(list(busy))
    sleeps = []
    res = check.run_check(measure_fn, frames=10, repeats=repeats, pause_s=7.0, window=window, sleep=sleeps.append)
    return res, window.made, sleeps


def test_check_verdict_follows_the_budget(no_bundle_build):
    ok, attempts, _ = _run(_fake_measure(0.2, 0.5))
    assert ok.passed and ok.verdict is check.Verdict.PASS and attempts == 1 and ok.p99_ms == pytest.approx(0.7)
    assert ok.speedup_p50 == pytest.approx(80.0 / 0.7)
    report = ok.report()
    assert "PASS" in report and "D (w0.25, 1/4) int8" in report and "RGBmod+D (w0.25, 1/4) int8" in report
    assert "attempt 1" in report and "quiet" in report
    bad, attempts, sleeps = _run(_fake_measure(0.3, 0.9))
    assert bad.verdict is check.Verdict.OVER_BUDGET and attempts == 1 and sleeps == []  # quiet: no repeat
    assert "FAIL (over budget)" in bad.report()


def test_check_repeats_on_a_busy_machine_and_says_so(no_bundle_build):
    busy, attempts, sleeps = _run(_fake_measure(0.3, 0.9), busy=[True, True, True])
    assert busy.verdict is check.Verdict.MACHINE_BUSY and not busy.passed
    assert attempts == 3 and sleeps == [7.0, 7.0] and len(busy.attempts) == 3
    report = busy.report()
    assert "NO VERDICT (machine busy)" in report and "BUSY" in report and "load average" in report
    # Busy first, then quiet and still over budget: the model is over budget.
    over, attempts, _ = _run(_fake_measure(0.3, 0.9), busy=[True, False])
    assert over.verdict is check.Verdict.OVER_BUDGET and attempts == 2


def test_check_keeps_the_most_accurate_candidate_that_fits(monkeypatch, tmp_path):
    accurate, fast = tmp_path / "accurate", tmp_path / "fast"
    monkeypatch.setattr(check, "rgbmod_candidates",
                        lambda: [(accurate, "trained accurate", 0.07), (fast, "trained fast", 0.10)])
    monkeypatch.setattr(check, "trained_int8", lambda variant, cfg: None)
    slow, quick = _fake_measure(0.3, 0.9), _fake_measure(0.2, 0.5)
    res, _, _ = _run(lambda case: slow(case) if case.bundle == accurate else quick(case))
    assert res.passed and res.which.startswith("trained fast") and "RE 0.070 -> 0.100" in res.which
    assert "over budget" in res.report() and "fits" in res.report()
    both_fit, _, _ = _run(quick)
    assert both_fit.which == "trained accurate"


def test_check_cli_exits_nonzero_when_budget_not_met(no_bundle_build, monkeypatch, capsys, tmp_path):
    out = tmp_path / "results"  # never the repo's docs/benchmarks: these figures are fakes
    monkeypatch.setattr(check, "measure", _fake_measure(0.4, 0.8))
    monkeypatch.setattr(check, "CpuWindow", FakeWindow([False]))
    assert cli.main(["--check", "--out", str(out), "--repeats", "1"]) == 1
    assert "FAIL (over budget): total p99 1.200 ms > budget 1.000 ms" in capsys.readouterr().out
    assert "FAIL" in (out / "check.md").read_text()
    monkeypatch.setattr(check, "measure", _fake_measure(0.1, 0.3))
    assert cli.main(["--check", "--out", str(out)]) == 0


def test_quick_never_writes_the_docs_and_default_out_is_not_docs(capsys):
    docs = cli.DOCS
    before = {p: p.stat().st_mtime_ns for p in docs.glob("*")} if docs.is_dir() else {}
    assert cli.main(["latency", "--quick", "--out", str(docs)]) == 2
    assert "never go into the docs" in capsys.readouterr().err
    assert cli.main(["--check", "--quick", "--out", str(docs / "sub")]) == 2
    after = {p: p.stat().st_mtime_ns for p in docs.glob("*")} if docs.is_dir() else {}
    assert before == after
    assert not cli.is_docs(cli.DEFAULT_OUT) and cli.is_docs(docs)
    assert cli.main(["--check", "--repeats", "0", "--out", "/tmp/x"]) == 2


def test_measure_through_the_runtime_with_a_fake_clock():
    """Every clock call advances 0.25 ms. Per frame the runtime reads the clock before and after
    read() (the in-memory source stamps arrival in between), after the gate, after the depth
    stage, around predict and at the end: source 0.5, gate / depth / inference 0.25 each,
    total (from arrival) 1.5, glue 0.75 ms."""
    from benchmarks.frames import frame_pool

    pool = frame_pool()  # 64 virtual DIGIT frames in contact, rendered once and cached
    ticks = itertools.count(step=250_000)
    res = measure(LatencyCase(None, "fp64", engine="polynomial", frames=12, warmup=2), pool, clock=lambda: next(ticks))
    s = res.stages
    assert s["source"].n == 12 and res.bare is None and math.isnan(res.overhead)
    assert s["source"].p50 == pytest.approx(0.5)
    for k in ("gate", "depth", "inference"):
        assert s[k].p50 == pytest.approx(0.25) and s[k].p99 == pytest.approx(0.25)
    assert s["total"].p99 == pytest.approx(1.5) and s["glue"].p50 == pytest.approx(0.75)
    assert s["gate+inference"].p50 == pytest.approx(0.5)
    assert "gate open" not in res.note  # every rendered frame is in contact


def test_memory_source_stamps_arrival_and_ends():
    from benchmarks.latency import MemorySource

    frames = np.arange(3, dtype=np.uint8)[:, None, None, None] * np.ones((1, 320, 240, 3), np.uint8)
    ticks = itertools.count(start=10, step=5)
    src = MemorySource(frames, 4, clock=lambda: next(ticks))
    got = list(src)
    assert [f.index for f in got] == [0, 1, 2, 3] and [f.arrival_ns for f in got] == [10, 15, 20, 25]
    assert [int(f.frame[0, 0, 0]) for f in got] == [0, 1, 2, 0]  # cycled, no copies needed
    assert np.shares_memory(got[3].frame, frames) and src.read() is None


def test_paced_memory_source_stamps_arrival_and_skips_what_a_late_reader_missed():
    import time

    from benchmarks.latency_page import PacedMemorySource

    frames = np.zeros((2, 320, 240, 3), np.uint8)
    src = PacedMemorySource(frames, fps=1000.0, n=200)
    a = src.read()
    assert a.index == 0 and a.arrival_ns >= a.timestamp_ns and a.meta["superseded"] == []
    time.sleep(0.02)  # 20 frame periods: the reader is late
    b = src.read()
    assert b.index >= 10 and b.arrival_ns == b.timestamp_ns  # it waited in the buffer since it fell due
    assert [k for k, _ in b.meta["superseded"]] == list(range(1, b.index)) and src.stats.dropped == b.index - 1
