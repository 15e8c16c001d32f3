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
                                "total": p(total), "gate+inference": p(gate + inference)}, gmacs=0.1)


def _fake_measure(gate_ms: float, inference_ms: float):
    def fake(case: LatencyCase) -> LatencyResult:
        if case.engine == "torch-eager":
            return _result(case, 0.2, 80.0)
        d = 2.5 if case.needs_depth else math.nan
        return _result(case, gate_ms, inference_ms, d)

    return fake


@pytest.fixture
def no_bundle_build(monkeypatch, tmp_path):
    monkeypatch.setattr(check, "rgbmod_candidates", lambda: [(tmp_path, "fake bundle", 0.07)])
    monkeypatch.setattr(check, "trained_int8", lambda variant, cfg: None)


def test_check_verdict_follows_the_budget(no_bundle_build):
    ok = check.run_check(_fake_measure(0.2, 0.5), frames=10)
    assert ok.passed and ok.p99_ms == pytest.approx(0.7)
    assert ok.speedup_p50 == pytest.approx(80.0 / 0.7)
    report = ok.report()
    assert "PASS" in report and "D (w0.25, 1/4) int8" in report and "RGBmod+D (w0.25, 1/4) int8" in report
    bad = check.run_check(_fake_measure(0.3, 0.9), frames=10)
    assert not bad.passed and "FAIL" in bad.report()


def test_check_keeps_the_most_accurate_candidate_that_fits(monkeypatch, tmp_path):
    accurate, fast = tmp_path / "accurate", tmp_path / "fast"
    monkeypatch.setattr(check, "rgbmod_candidates",
                        lambda: [(accurate, "trained accurate", 0.07), (fast, "trained fast", 0.10)])
    monkeypatch.setattr(check, "trained_int8", lambda variant, cfg: None)
    slow, quick = _fake_measure(0.3, 0.9), _fake_measure(0.2, 0.5)
    res = check.run_check(lambda case: slow(case) if case.bundle == accurate else quick(case), frames=10)
    assert res.passed and res.which.startswith("trained fast") and "RE 0.070 -> 0.100" in res.which
    assert "over budget" in res.report() and "fits" in res.report()
    both_fit = check.run_check(quick, frames=10)
    assert both_fit.which == "trained accurate"


def test_check_cli_exits_nonzero_when_budget_not_met(no_bundle_build, monkeypatch, capsys, tmp_path):
    out = tmp_path / "docs"  # never the repo's docs/benchmarks: these figures are fakes
    monkeypatch.setattr(check, "measure", _fake_measure(0.4, 0.8))
    assert cli.main(["--check", "--out", str(out)]) == 1
    assert "FAIL: gate + inference p99 1.200 ms > budget 1.000 ms" in capsys.readouterr().out
    assert "FAIL" in (out / "check.md").read_text()
    monkeypatch.setattr(check, "measure", _fake_measure(0.1, 0.3))
    assert cli.main(["--check", "--out", str(out)]) == 0


def test_measure_stage_arithmetic_with_a_fake_clock(monkeypatch):
    """Every clock call advances 0.25 ms: each stage reads exactly 0.25 ms, total 0.75 ms."""
    from benchmarks.frames import frame_pool

    pool = frame_pool()  # 64 virtual DIGIT frames in contact, rendered once and cached
    ticks = itertools.count(step=250_000)
    res = measure(LatencyCase(None, "fp64", engine="polynomial", frames=12, warmup=2), pool, clock=lambda: next(ticks))
    s = res.stages
    assert s["source"].n == 12
    for k in ("source", "gate", "depth", "inference"):
        assert s[k].p50 == pytest.approx(0.25) and s[k].p99 == pytest.approx(0.25)
    assert s["total"].p99 == pytest.approx(0.75) and s["gate+inference"].p50 == pytest.approx(0.5)
    assert "gate open" not in res.note  # every rendered frame is in contact
