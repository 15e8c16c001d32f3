"""``tactile-force bench``: the report.json contract, exit codes, no torch, and the same RE as ``run``.

Real ONNX Runtime, OpenCV and the shipped default bundle; no timing assertions (the verdict
of a real run depends on the machine, so tests accept 0 or 1 where a real budget is judged).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from tactile_force.benchmarks.bench import (
    REPORT_JSON,
    BenchReport,
    contact_frames,
    overall_verdict,
    read_report,
)
from tactile_force.benchmarks.harness.budget import BudgetVerdict, judge
from tactile_force.benchmarks.harness.machine import MachineState
from tactile_force.edge.cli import main
from tactile_force.edge.scene import default_bundle_path, shipped_bundles

# 200 fps keeps the cadence run short (150 frames with the warm-up: 0.75 s per bundle); 120
# readings leave room for a few frames a busy test machine is late for above the 100 a p99 needs
FAST = ["--frames", "100", "--fps", "200", "--cadence-frames", "120", "--repeats", "1"]


@pytest.fixture(scope="module")
def synth_dir(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("bench_synth") / "data"
    assert main(["synth", "--out", str(out), "--n", "24", "--seed", "3", "--no-progress"]) == 0
    return out


def test_shipped_bundles_start_with_the_default():
    found = list(shipped_bundles().values())
    assert found and found[0] == default_bundle_path()
    assert all((p / "model.json").is_file() for p in found)


def test_report_json_is_the_documented_contract(tmp_path, capsys):
    out = tmp_path / "bench"
    rc = main(["bench", *FAST, "--out", str(out)])
    assert rc in (0, 1)  # PASS, or over budget / busy on a loaded test machine
    raw = json.loads((out / REPORT_JSON).read_text())
    assert {"schema", "machine", "budget_ms", "verdict", "bundles"} <= raw.keys()
    assert raw["budget_ms"] == 1.0 and raw["verdict"] in ("PASS", "OVER_BUDGET", "MACHINE_BUSY", "NO_READINGS")
    assert len(raw["bundles"]) == len(shipped_bundles())
    assert {"cpu", "cores"} <= raw["machine"].keys()
    b = raw["bundles"][0]
    assert {"path", "variant", "precision", "total_ms", "stages_ms", "error", "verdict"} <= b.keys()
    assert {"p50", "p99"} <= b["total_ms"].keys() and b["total_ms"]["p99"] >= b["total_ms"]["p50"] > 0
    assert {"gate", "inference", "total"} <= b["stages_ms"].keys() and "depth" not in b["stages_ms"]
    assert b["error"] is None and b["variant"] == "rgbmod" and b["precision"] == "fp32"
    assert Path(b["path"]) == default_bundle_path()
    c = b["cadence"]
    assert {"fps", "total_ms", "cpu_share"} <= c.keys() and c["fps"] == 200.0
    assert {"p50", "p90", "p99", "mean", "n"} <= c["total_ms"].keys() and 0 < c["total_ms"]["n"] <= 120
    assert 0 < c["cpu_share"] <= 1
    report = read_report(out / REPORT_JSON)  # parses into the typed dataclasses
    assert isinstance(report, BenchReport) and report.bundles[0].total_ms.n == 100
    assert report.to_json() == raw  # the cadence record round-trips
    assert all(x.attempts[-1].total_p99_ms == x.cadence.total_ms.p99 for x in report.bundles if x.cadence)
    assert (rc == 0) == report.passed
    assert (out / "report.md").read_text().startswith("# tactile-force bench")
    import cv2

    assert cv2.imread(str(out / "pareto.png")) is not None
    printed = capsys.readouterr().out
    assert "verdict:" in printed and report.bundles[0].name in printed
    assert "200 fps total p99" in printed and "200 fps total p99" in (out / "report.md").read_text()
    # the host every figure was measured on: printed, in report.json and in report.md
    from tactile_force.edge.report.host import cpu_line, cpu_model

    assert raw["machine"]["cpu"] == cpu_model() and raw["machine"]["cpu"] in (out / "report.md").read_text()
    assert cpu_line(cpu_model(), raw["machine"]["cores"]) in printed.splitlines()


def _report_raw(cadence: dict | None) -> dict:
    t = {"p50": 0.4, "p90": 0.5, "p99": 0.6, "mean": 0.42, "n": 1000}
    bundle = {"path": "b", "name": "b", "variant": "rgbmod", "precision": "int8-static", "total_ms": t,
              "stages_ms": {"total": t}, "error": None, "manifest_re": None, "verdict": "PASS", "attempts": [],
              "note": ""}
    if cadence is not None:
        bundle["cadence"] = cadence
    return {"schema": "tactile-force-bench/1", "budget_ms": 1.0, "threads": 1, "frames": 1000, "verdict": "PASS",
            "machine": {"cpu": "x", "cores": 1, "ram_gib": None, "os": "", "python": "", "versions": "",
                        "background_load": ""}, "bundles": [bundle], "command": "", "image_path": ""}


def test_the_cadence_record_round_trips_and_an_older_report_still_reads():
    from tactile_force.benchmarks.bench import Cadence, Timing
    from tactile_force.edge.typed_json import TypedJsonError

    cadence = {"fps": 60.0, "total_ms": {"p50": 0.8, "p90": 0.9, "p99": 1.2, "mean": 0.82, "n": 300},
               "cpu_share": 0.07, "missed": 2,
               "bare_ms": {"p50": 0.5, "p90": 0.6, "p99": 0.7, "mean": 0.52, "n": 300}}
    raw = _report_raw(cadence)
    r = BenchReport.from_json(raw)
    assert r.bundles[0].cadence == Cadence(60.0, Timing(0.8, 0.9, 1.2, 0.82, 300), 0.07, 2,
                                           Timing(0.5, 0.6, 0.7, 0.52, 300))
    assert r.bundles[0].judged_ms.p99 == 1.2 and r.to_json() == raw
    no_floor = {k: v for k, v in cadence.items() if k != "bare_ms"}  # written before the floor was measured
    assert BenchReport.from_json(_report_raw(no_floor)).bundles[0].cadence.bare_ms is None
    old = BenchReport.from_json(_report_raw(None))  # written before the cadence was measured
    assert old.bundles[0].cadence is None and old.bundles[0].judged_ms.p99 == 0.6
    with pytest.raises(TypedJsonError, match=r"cadence\.fps"):
        BenchReport.from_json(_report_raw({**cadence, "fps": 0}))


def test_a_graph_that_alone_misses_the_budget_at_the_cadence_is_named_as_the_floor():
    from tactile_force.benchmarks.bench import markdown, text_table

    slow = {"p50": 0.9, "p90": 1.1, "p99": 1.3, "mean": 0.95, "n": 300}
    cadence = {"fps": 60.0, "total_ms": {"p50": 1.4, "p90": 1.6, "p99": 1.9, "mean": 1.45, "n": 300},
               "cpu_share": 0.1, "missed": 0, "bare_ms": slow}
    raw = _report_raw(cadence)
    raw["bundles"][0]["verdict"] = raw["verdict"] = "OVER_BUDGET"
    over = BenchReport.from_json(raw)
    for text in (text_table(over), markdown(over)):
        assert "its graph alone" in text and "1.300 ms > the 1 ms budget" in text and "edge/models/default" in text
    fast_floor = dict(cadence, bare_ms={**slow, "p99": 0.6})  # the graph fits: the runtime around it does not
    raw["bundles"][0]["cadence"] = fast_floor
    assert "its graph alone" not in text_table(BenchReport.from_json(raw))


@pytest.mark.parametrize("value, expected", [("0", "expected a number in [0.01, 10000]"),
                                             ("nan", "expected a finite number in [0.01, 10000]"),
                                             ("-60", "expected a number in [0.01, 10000]"),
                                             ("1e-300", "expected a number in [0.01, 10000]"),
                                             ("x", "'x' is not a number")])
def test_a_bad_fps_exits_2_naming_the_flag(tmp_path, capsys, value, expected):
    assert main(["bench", "--fps", value, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "argument --fps" in err and expected in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_bench_measures_at_the_cadence_with_the_paced_source_and_judges_that(monkeypatch):
    """Each attempt reads frames from a paced source at --fps; the verdict rests on those
    readings (their count and their p99), not on the back-to-back ones."""
    import tactile_force.benchmarks.harness.latency as latency
    from tactile_force.benchmarks.bench import bench_bundle

    made = []

    class Paced(latency.PacedMemorySource):
        def __init__(self, *args, **kwargs) -> None:
            super().__init__(*args, **kwargs)
            made.append(self)

    monkeypatch.setattr(latency, "PacedMemorySource", Paced)
    pool = contact_frames(8)
    # too few back-to-back readings for a p99, enough at the cadence: judged at the cadence
    r = bench_bundle(default_bundle_path(), pool, frames=5, warmup=5, repeats=1, budget_ms=1000.0,
                     window=_Window([False]), fps=200.0, cadence_frames=120)
    # the runtime's warm-up trial comes on top of the warm-up frames: the 120 count from its decision
    assert [(s.n, s.period) for s in made] == [(125 + latency.auto_trial_frames(200.0), 5_000_000)]
    c = r.cadence
    assert c is not None and c.fps == 200.0 and 0 < c.cpu_share <= 1
    assert c.total_ms.n <= 120 <= c.total_ms.n + c.missed and r.total_ms.n == 5
    assert len(r.attempts) == 1 and r.attempts[0].total_p99_ms == c.total_ms.p99 == r.judged_ms.p99
    assert r.verdict == "PASS"  # 1 s budget: passes on the cadence's >= 100 readings, never on 5
    assert c.bare_ms is not None and c.bare_ms.n == 120 and 0 < c.bare_ms.p50 <= c.bare_ms.p99  # the floor
    # and the other way round: plenty back to back, too few at the cadence
    few = bench_bundle(default_bundle_path(), pool, frames=120, warmup=5, repeats=1, budget_ms=1000.0,
                       window=_Window([False]), fps=200.0, cadence_frames=5)
    assert few.verdict == "TOO_FEW_READINGS" and few.cadence is not None and few.cadence.total_ms.n <= 5
    # study's use: no fps, back to back only and judged so
    made.clear()
    b2b = bench_bundle(default_bundle_path(), pool, frames=120, warmup=5, repeats=1, budget_ms=1000.0,
                       window=_Window([False]))
    assert made == [] and b2b.cadence is None and b2b.verdict == "PASS"


def test_a_wrong_report_is_refused_naming_the_field(tmp_path):
    from tactile_force.edge.typed_json import TypedJsonError

    good = {"schema": "tactile-force-bench/1", "budget_ms": 1.0, "threads": 1, "frames": 1, "verdict": "PASS",
            "machine": {"cpu": "x", "cores": 1, "ram_gib": None, "os": "", "python": "", "versions": "",
                        "background_load": ""}, "bundles": []}
    BenchReport.from_json(good)
    with pytest.raises(TypedJsonError, match="budget_ms"):
        BenchReport.from_json({**good, "budget_ms": "fast"})


def test_a_tiny_budget_exits_1_over_budget_or_busy(tmp_path):
    out = tmp_path / "b"
    assert main(["bench", *FAST, "--bundle", str(default_bundle_path()), "--budget-ms", "0.001",
                 "--out", str(out)]) == 1
    r = read_report(out / REPORT_JSON)
    assert r.verdict in ("OVER_BUDGET", "MACHINE_BUSY") and not r.passed
    assert r.bundles[0].verdict == r.verdict and len(r.bundles[0].attempts) == 1


@pytest.mark.parametrize("argv", [
    ["--bundle", "no/such/bundle"],
    ["--background", "x.png"],
    ["--data", "no/such/folder"],
    ["--frames", "0"],
    ["--budget-ms", "-1"],
])
def test_bad_input_exits_2_with_one_line(tmp_path, capsys, argv):
    assert main(["bench", *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and not (tmp_path / "o" / REPORT_JSON).exists()


def test_unlabelled_data_is_bad_input(tmp_path, capsys):
    import cv2

    (tmp_path / "pngs").mkdir()
    cv2.imwrite(str(tmp_path / "pngs" / "0.png"), np.full((320, 240, 3), 90, np.uint8))
    assert main(["bench", *FAST, "--data", str(tmp_path / "pngs"), "--out", str(tmp_path / "o")]) == 2


def test_bench_data_gives_the_same_error_as_run(tmp_path, capsys, synth_dir):
    bundle = str(default_bundle_path())
    assert main(["run", "--source", str(synth_dir), "--bundle", bundle, "--out", str(tmp_path / "r.csv")]) == 0
    err = capsys.readouterr().err
    m = re.search(r"error vs truth over (\d+) CNN readings: RE ([\d.]+) \+- [\d.]+, MAE ([\d.]+)", err)
    assert m, err
    out = tmp_path / "bench"
    assert main(["bench", *FAST, "--bundle", bundle, "--data", str(synth_dir), "--out", str(out)]) in (0, 1)
    e = read_report(out / REPORT_JSON).bundles[0].error
    assert e is not None and e.re_mean is not None
    assert e.n == int(m.group(1)) and f"{e.re_mean:.3f}" == m.group(2) and f"{e.mae_mean:.3f}" == m.group(3)
    assert sum(b.n for b in e.per_bin.values()) == e.n and e.frames_with_truth == 24
    assert "| force bin (N) |" in (out / "report.md").read_text()


def test_bench_needs_no_torch_onnx_or_matplotlib(tmp_path):
    code = ("import sys, json\n"
            "for m in ('torch', 'onnx', 'matplotlib'): sys.modules[m] = None  # importing one would fail\n"
            "import tactile_force.benchmarks.bench, tactile_force.benchmarks.harness.budget\n"
            "import tactile_force.benchmarks.harness.latency, tactile_force.benchmarks.harness.machine\n"
            "import tactile_force.edge.cli.bench, tactile_force.edge.report.plots\n"
            "from tactile_force.edge.cli import main\n"
            "rc = main(['bench', '--frames', '10', '--fps', '200', '--cadence-frames', '10', '--repeats', '1', "
            f"'--out', {str(tmp_path / 'o')!r}])\n"
            "print(json.dumps([rc, sorted(m for m in sys.modules if m.split('.')[0] in "
            "('torch', 'onnx', 'matplotlib') and sys.modules[m] is not None)]))\n")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    rc, heavy = json.loads(run.stdout.strip().splitlines()[-1])
    assert rc in (0, 1) and heavy == []
    assert (tmp_path / "o" / REPORT_JSON).is_file()


def test_contact_frames_open_the_gate_on_every_frame():
    pool = contact_frames(8, seed=1)
    assert pool.rgb.shape == (8, 320, 240, 3) and pool.background.shape[1:] == (320, 240, 3)
    assert all(_fresh(pool).update(f).contact for f in pool.rgb)
    assert np.all((pool.force >= 1.5) & (pool.force <= 14.5))


def _fresh(pool):
    from tactile_force.edge.gate.contact_gate import ContactGate

    g = ContactGate()
    g.capture_background(pool.background)
    return g


class _Window:
    """A fake machine watcher (hardware boundary): each stop() reports the next busy flag."""

    def __init__(self, busy: list[bool]) -> None:
        self.busy = busy

    def __call__(self):
        outer = self

        class W:
            def stop(self) -> MachineState:
                return MachineState(0.1, 0.1, 1000.0, 1000.0, 0.5 if outer.busy[0] else 0.0, 1.0, outer.busy.pop(0))
        return W()


@pytest.mark.parametrize("p99s, busy, verdict, n", [
    ([0.5], [False], BudgetVerdict.PASS, 1),
    ([2.0], [False], BudgetVerdict.OVER_BUDGET, 1),
    ([2.0, 3.0, 2.5], [True, True, True], BudgetVerdict.MACHINE_BUSY, 3),
    ([2.0, 0.8], [True, True], BudgetVerdict.PASS, 2),
])
def test_judge_repeats_only_after_a_busy_attempt_over_budget(p99s, busy, verdict, n):
    left = list(p99s)
    kept, v, attempts = judge(lambda: (left[0], left.pop(0)), 1.0, repeats=3, pause_s=0.0, window=_Window(busy),
                              sleep=lambda s: None)
    assert v is verdict and len(attempts) == n and kept == min(p99s[:n])


def test_overall_verdict():
    assert overall_verdict(["PASS", "PASS"]) == "PASS"
    assert overall_verdict(["PASS", "MACHINE_BUSY", "OVER_BUDGET"]) == "OVER_BUDGET"
    assert overall_verdict(["PASS", "MACHINE_BUSY"]) == "MACHINE_BUSY"
    assert overall_verdict(["NO_READINGS", "MACHINE_BUSY"]) == "NO_READINGS"
    assert overall_verdict([]) == "MACHINE_BUSY"


def test_too_few_readings_give_no_verdict(tmp_path, capsys):
    out = tmp_path / "b"
    rc = main(["bench", "--frames", "5", "--fps", "200", "--cadence-frames", "5", "--repeats", "1",
               "--bundle", str(default_bundle_path()),
               "--budget-ms", "1000", "--out", str(out)])
    assert rc == 1  # no verdict: never PASS from 5 readings, however fast
    r = read_report(out / REPORT_JSON)
    assert r.verdict == "TOO_FEW_READINGS" and r.bundles[0].verdict == "TOO_FEW_READINGS"
    assert "too few readings" in r.bundles[0].note and "too few readings" in (out / "report.md").read_text()
    assert "too few readings" in capsys.readouterr().out


def _user_folder(path: Path) -> Path:
    path.mkdir(parents=True)
    (path / "report.md").write_text("my own notes\n")
    (path / "report.json").write_text("{}\n")
    return path


def test_an_existing_out_is_never_replaced_without_force(tmp_path, capsys):
    out = _user_folder(tmp_path / "mine")
    assert main(["bench", *FAST, "--bundle", str(default_bundle_path()), "--out", str(out)]) == 2
    assert (out / "report.md").read_text() == "my own notes\n"
    assert "--force" in capsys.readouterr().err
    # --force replaces only an earlier bench result, never a folder of the user's files
    assert main(["bench", *FAST, "--bundle", str(default_bundle_path()), "--out", str(out), "--force"]) == 2
    assert (out / "report.md").read_text() == "my own notes\n"


def test_force_replaces_an_earlier_result_but_not_a_file_added_to_it(tmp_path):
    out = tmp_path / "b"
    args = ["bench", *FAST, "--bundle", str(default_bundle_path()), "--budget-ms", "1000", "--out", str(out)]
    assert main(args) in (0, 1)
    first = (out / REPORT_JSON).read_text()
    assert main([*args, "--force"]) in (0, 1)
    assert (out / REPORT_JSON).read_text() != first  # a new measurement, published whole
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging left behind
    (out / "NOTES.txt").write_text("keep me")
    assert main([*args, "--force"]) == 2
    assert (out / "NOTES.txt").read_text() == "keep me"


@pytest.mark.parametrize("where", ["data", "bundle"])
def test_out_inside_an_input_is_refused(tmp_path, capsys, synth_dir, where):
    import shutil

    bundle = tmp_path / "bundle"
    shutil.copytree(default_bundle_path(), bundle)
    inside = (synth_dir if where == "data" else bundle) / "bench_out"
    before = sorted(p.name for p in inside.parent.iterdir())
    rc = main(["bench", *FAST, "--bundle", str(bundle), "--data", str(synth_dir), "--out", str(inside), "--force"])
    assert rc == 2 and "input" in capsys.readouterr().err
    assert sorted(p.name for p in inside.parent.iterdir()) == before


def test_interrupted_bench_exits_130_and_leaves_no_output(tmp_path):
    """SIGINT while measuring: exit 130 (143 for SIGTERM), --out not made, no staging left."""
    import signal
    import subprocess
    import sys
    import time

    for sig, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143)):
        out = tmp_path / f"b{int(sig)}"
        proc = subprocess.Popen([sys.executable, "-m", "tactile_force.edge.cli", "bench", "--frames", "100000",
                                 "--repeats", "1", "--bundle", str(default_bundle_path()), "--out", str(out)],
                                stderr=subprocess.PIPE, text=True)
        assert proc.stderr is not None and proc.stderr.readline().startswith("bench:")  # measuring starts
        time.sleep(1.5)
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=120)
        assert proc.returncode == code, err
        assert "Traceback" not in err and not out.exists()
        assert not [p for p in tmp_path.iterdir() if p.name.startswith(f".{out.name}.")]


def test_bench_refuses_a_bundle_whose_manifest_the_graph_contradicts(tmp_path):
    """An fp32 graph whose manifest says int8-static: write_bundle refuses to write it, and a
    hand-edited one is refused by bench as by every loader (bundle verify refuses it too),
    naming the bundle and the field; the shipped bundle's graph holds what its manifest says."""
    pytest.importorskip("onnx", reason="building the fp32 test graph needs the 'onnx' package (dev extra)")
    import hashlib

    from tactile_force.benchmarks.bench import bench_bundle
    from tactile_force.edge.bundle.store import write_bundle
    from tactile_force.edge.errors import BundleError

    from tests.conftest import mean_manifest, mean_model_bytes

    m = mean_manifest("rgbmod", "fp32-says-int8")
    m.precision = type(m.precision)("int8-static")
    graph = mean_model_bytes(20.0, 0.0, False)
    with pytest.raises(BundleError, match="precision: the manifest says int8-static but the graph is fp32"):
        write_bundle(tmp_path / "refused", graph, m)
    lie = tmp_path / "lie"
    lie.mkdir()
    m.sha256 = hashlib.sha256(graph).hexdigest()
    (lie / "model.onnx").write_bytes(graph)
    (lie / "model.json").write_text(m.to_json())
    pool = contact_frames(8)
    with pytest.raises(BundleError, match=f"{lie}.*precision: the manifest says int8-static but the graph is fp32"):
        bench_bundle(lie, pool, frames=5, repeats=1, warmup=1)
    honest = bench_bundle(shipped_bundles()["rgbmod_int8"], pool, frames=5, repeats=1, warmup=1)
    assert honest.precision == "int8-static" and "manifest says" not in honest.note
