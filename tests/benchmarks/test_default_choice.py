"""Which bundle ships as the default (benchmarks/default_bundle.py): the Pareto front of (RE, p99 at
the cadence) per bench run, the choice over runs, the page from earlier reports, and bad --reports
refused in one line before any work."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from benchmarks.bench_contract import BenchReport
from benchmarks.default_bundle import choose, front, points

REPO = Path(__file__).resolve().parents[2]


def _timing(p50: float, p99: float) -> dict:
    return {"p50": p50, "p90": p99, "p99": p99, "mean": p50, "n": 300}


def _bundle(name: str, variant: str, re: float, p99: float) -> dict:
    return {"path": f"/x/edge/models/{name}", "name": name, "variant": variant, "precision": "fp32",
            "total_ms": _timing(0.3, 0.5), "stages_ms": {}, "error": None, "manifest_re": re,
            "verdict": "PASS" if p99 <= 1.0 else "OVER_BUDGET",
            "cadence": {"fps": 60.0, "total_ms": _timing(p99 * 0.8, p99), "cpu_share": 0.1, "missed": 0,
                        "bare_ms": _timing(p99 * 0.5, p99 * 0.6)}}


def _report(*bundles: dict) -> dict:
    return {"schema": "tactile-force-bench/1", "budget_ms": 1.0, "threads": 1, "frames": 1000,
            "verdict": "OVER_BUDGET", "machine": {"cpu": "Test CPU", "cores": 2, "ram_gib": None, "os": "",
                                                  "python": "", "versions": "", "background_load": ""},
            "bundles": list(bundles), "command": "tactile-force bench"}


def _run(*bundles: dict):
    return points(BenchReport.from_json(_report(*bundles)))


def test_the_front_holds_every_bundle_no_other_beats_in_both():
    run = _run(_bundle("a", "rgbmod", 0.08, 2.3), _bundle("b", "rgbmod", 0.07, 1.3), _bundle("c", "rgbmod", 0.05, 3.0),
               _bundle("d", "d", 0.01, 0.5))
    assert front(run) == {"b", "c"}  # a is beaten by b in both; d reads depth and does not compete
    assert front(run, everyone=True) == {"d"}


def test_the_choice_is_the_bundle_on_the_front_most_often_then_the_faster():
    runs = [_run(_bundle("a", "rgbmod", 0.08, 1.2), _bundle("b", "rgbmod", 0.07, 1.3)),
            _run(_bundle("a", "rgbmod", 0.08, 1.4), _bundle("b", "rgbmod", 0.07, 1.3)),
            _run(_bundle("a", "rgbmod", 0.08, 1.5), _bundle("b", "rgbmod", 0.07, 1.3))]
    assert choose(runs) == "b"  # on the front in 3 of 3, a in 1 of 3
    tie = [_run(_bundle("a", "rgbmod", 0.08, 1.2), _bundle("b", "rgbmod", 0.07, 1.3))]
    assert choose(tie) == "a"  # both on the front once: the lower median p99


def test_the_page_from_earlier_reports_names_the_choice(tmp_path):
    paths = []
    for k, p99 in enumerate((1.3, 1.25, 1.4, 1.35, 1.3)):
        d = tmp_path / f"run{k}"
        d.mkdir()
        (d / "report.json").write_text(json.dumps(_report(_bundle("int8", "rgbmod", 0.080, 2.3),
                                                          _bundle("small", "rgbmod", 0.072, p99))))
        (d / "report.md").write_text("# tactile-force bench\n\nCommit: abc1234\n")
        paths.append(str(d / "report.json"))
    out = tmp_path / "pages"
    p = subprocess.run([sys.executable, "-m", "benchmarks", "default-bundle", "--reports", *paths, "--out", str(out)],
                       capture_output=True, text=True, cwd=REPO, timeout=120)
    assert p.returncode == 0, p.stderr
    page = (out / "default_bundle.md").read_text()
    assert "**Chosen: small**, on the front in 5 of 5 runs" in page and "measured at commit abc1234" in page
    assert "Test CPU" in page and "| int8 | int8 | rgbmod | 0.080 |" in page
    assert json.loads((out / "default_bundle.json").read_text())["chosen"] == "small"


def test_bad_reports_are_refused_in_one_line_before_any_work(tmp_path):
    (tmp_path / "bad.json").write_text("{}")
    for arg, said in ((tmp_path / "none.json", "not a file"), (tmp_path / "bad.json", "not a bench report.json")):
        p = subprocess.run([sys.executable, "-m", "benchmarks", "default-bundle", "--reports", str(arg),
                            "--out", str(tmp_path / "o")], capture_output=True, text=True, cwd=REPO, timeout=120)
        assert p.returncode == 2 and said in p.stderr and str(arg) in p.stderr and "Traceback" not in p.stderr
        assert not (tmp_path / "o" / "default_bundle.md").exists()
