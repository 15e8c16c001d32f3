"""``tactile-force study`` on a tiny model: the study.json contract, the Pareto bundles, the
recommendation, and the error it reports is run's error (real quantization, ONNX Runtime)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest
import torch
from tactile_force.edge.cli import main
from tactile_force.export import ExportOptions, ForceNet, ModelSpec, build_model, export_bundle
from tactile_force.export.study import StudyReport, grid, read_study


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> tuple[Path, Path]:
    """(fp32 bundle of a tiny random-weight RGBmod, 24 synthetic labelled frames)."""
    root = tmp_path_factory.mktemp("study")
    data = root / "data"
    assert main(["synth", "--out", str(data), "--n", "24", "--seed", "5", "--no-progress"]) == 0
    torch.manual_seed(0)
    net = ForceNet(build_model("rgbmod", 0.125), ModelSpec("rgbmod", 0.125, 1 / 8))
    with torch.no_grad():  # outputs near 8 N: inside the valid range, so RE is defined
        [m for m in net.modules() if isinstance(m, torch.nn.Linear)][-1].bias.add_(8.0)
    bundle = root / "fp32"
    export_bundle(net, bundle, ExportOptions(parity_tol_n=1e-3, name="tiny-fp32", trained_on="random weights"))
    return bundle, data


def test_study_on_a_tiny_model_writes_the_contract(tmp_path, capsys, tiny):
    bundle, data = tiny
    out = tmp_path / "study"
    rc = main(["study", str(bundle), "--data", str(data), "--out", str(out), "--quick", "--max-configs", "2",
               "--sensitivity-nodes", "2", "--frames", "100", "--budget-ms", "1000"])
    assert rc == 0, capsys.readouterr().err
    raw = json.loads((out / "study.json").read_text())
    configs = raw["configurations"]
    assert [c["name"] for c in configs[:3]] == ["fp32", "int8-dynamic", "int8-static minmax per-channel"]
    for c in configs:
        assert {"name", "settings", "error", "latency_ms"} <= c.keys()
        assert c["error"]["re_mean"] is not None and c["latency_ms"]["p99"] >= c["latency_ms"]["p50"] > 0
        assert c["settings"]["mode"] in ("fp32", "fp16", "int8-dynamic", "int8-static")
    assert configs[0]["error"]["vs_fp32_mae"] == 0.0
    assert configs[2]["error"]["n_vs_fp32"] == configs[0]["error"]["n"]
    report = read_study(out / "study.json")
    assert isinstance(report, StudyReport) and report.same_frames
    # within a 1000 ms budget every configuration fits: the recommendation is the most accurate one
    best = min((c.error.re_mean, c.name) for c in report.configurations if c.error and c.error.re_mean is not None)
    assert report.recommended == best[1]
    assert len(report.sensitivity) == 2 and report.sensitivity_base == "int8-static minmax per-channel"
    # the Pareto front's bundles are kept; the others are removed
    for c in report.configurations:
        if c.name == "fp32":
            continue
        folder = out / "bundles" / re.sub(r"[^A-Za-z0-9.+-]+", "_", c.name).strip("_")
        assert (folder / "model.json").is_file() == (c.pareto or c.name == report.recommended), c.name
        assert (c.bundle is not None) == folder.is_dir()
    assert "recommended" in (out / "study.md").read_text().lower()
    import cv2

    assert cv2.imread(str(out / "pareto.png")) is not None
    printed = capsys.readouterr().out
    assert f"recommended (most accurate with p99 <= 1000 ms): {report.recommended}" in printed


def test_study_error_is_runs_error(tmp_path, capsys, tiny):
    bundle, data = tiny
    assert main(["run", "--source", str(data), "--bundle", str(bundle), "--out", str(tmp_path / "r.csv")]) == 0
    m = re.search(r"error vs truth over (\d+) CNN readings: RE ([\d.]+)", capsys.readouterr().err)
    assert m
    out = tmp_path / "s"
    main(["study", str(bundle), "--data", str(data), "--out", str(out), "--quick", "--max-configs", "0",
          "--sensitivity-nodes", "0", "--frames", "5"])
    fp32 = read_study(out / "study.json").configurations[0]
    assert fp32.error is not None and fp32.error.n == int(m.group(1)) and f"{fp32.error.re_mean:.3f}" == m.group(2)


def test_grid_covers_methods_granularity_and_kept_nodes():
    full = grid("conv1")
    modes = {s.mode for _, s in full}
    assert modes == {"int8-dynamic", "fp16", "int8-static"}
    static = [s for _, s in full if s.mode == "int8-static"]
    assert {(s.method, s.per_channel, tuple(s.keep_float)) for s in static} == {
        (m, pc, k) for m in ("minmax", "entropy", "percentile") for pc in (True, False) for k in ((), ("conv1",))}
    assert len(grid("conv1", quick=True)) == 3


@pytest.mark.parametrize("argv", [["x", "--data", "nowhere"], ["no/such/bundle", "--data", "."]])
def test_bad_input_exits_2(tmp_path, argv, capsys):
    assert main(["study", *argv, "--out", str(tmp_path / "o")]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_an_int8_bundle_is_refused(tmp_path, capsys, tiny):
    from tactile_force.edge.scene import default_bundle_path

    _, data = tiny
    int8 = default_bundle_path().parent / "rgbmod_int8"
    assert main(["study", str(int8), "--data", str(data), "--out", str(tmp_path / "o")]) == 2
    assert "fp32" in capsys.readouterr().err


def test_study_without_torch_names_the_extra():
    code = ("import sys; sys.modules['torch'] = None; sys.modules['onnx'] = None; "
            "from tactile_force.edge.cli import main; sys.exit(main(['study', '--help']))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert run.returncode == 2 and "'export' extra" in run.stderr and "Traceback" not in run.stderr


QUICK = ["--quick", "--max-configs", "1", "--sensitivity-nodes", "0"]


def test_a_second_study_never_deletes_the_first(tmp_path, capsys, tiny):
    bundle, data = tiny
    out = tmp_path / "s"
    assert main(["study", str(bundle), "--data", str(data), "--out", str(out), *QUICK, "--frames", "5"]) == 1
    first = sorted(str(p.relative_to(out)) for p in out.rglob("*"))
    assert any(p.startswith("bundles") for p in first) or (out / "study.json").is_file()
    # again without --force: refused before any work, the first study intact
    assert main(["study", str(bundle), "--data", str(data), "--out", str(out), *QUICK, "--frames", "5"]) == 2
    assert "--force" in capsys.readouterr().err
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == first
    # the user's own file inside the earlier result: --force refuses to delete it
    kept = next(p for p in out.rglob("*") if p.is_dir())
    (kept / "NOTES.txt").write_text("mine")
    assert main(["study", str(bundle), "--data", str(data), "--out", str(out), *QUICK, "--frames", "5",
                 "--force"]) == 2
    assert (kept / "NOTES.txt").read_text() == "mine"


@pytest.mark.parametrize("where", ["source", "inside-source", "data"])
def test_out_that_is_or_lies_in_an_input_is_refused(tmp_path, capsys, tiny, where):
    bundle, data = tiny
    out = {"source": bundle, "inside-source": bundle / "study", "data": data / "study"}[where]
    before = sorted(p.name for p in out.parent.iterdir())
    rc = main(["study", str(bundle), "--data", str(data), "--out", str(out), *QUICK, "--frames", "5", "--force"])
    err = capsys.readouterr().err
    assert rc == 2 and "input" in err and "internal error" not in err
    assert sorted(p.name for p in out.parent.iterdir()) == before


def test_too_few_readings_recommend_nothing(tmp_path, capsys, tiny):
    bundle, data = tiny
    out = tmp_path / "s"
    rc = main(["study", str(bundle), "--data", str(data), "--out", str(out), *QUICK, "--frames", "5",
               "--budget-ms", "1000"])
    assert rc == 1
    report = read_study(out / "study.json")
    assert report.recommended is None and "too few readings" in report.note
    assert not any(c.within_budget for c in report.configurations)
    assert "too few readings" in (out / "study.md").read_text()
    assert "too few readings" in capsys.readouterr().out


def test_too_few_labelled_frames_is_bad_input(tmp_path, capsys, tiny):
    bundle, _ = tiny
    data = tmp_path / "two"
    assert main(["synth", "--out", str(data), "--n", "2", "--seed", "1", "--no-progress"]) == 0
    capsys.readouterr()
    rc = main(["study", str(bundle), "--data", str(data), "--out", str(tmp_path / "s"), *QUICK, "--frames", "5"])
    err = capsys.readouterr().err
    assert rc == 2 and "at least 10" in err and "internal error" not in err
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("sig", ["SIGINT", "SIGTERM"])
def test_an_interrupted_study_leaves_nothing_half_made(tmp_path, tiny, sig):
    import signal
    import time

    bundle, data = tiny
    out = tmp_path / "s"
    proc = subprocess.Popen([sys.executable, "-m", "tactile_force.edge.cli", "study", str(bundle), "--data", str(data),
                             "--out", str(out), "--frames", "100", "--sensitivity-nodes", "0"],
                            stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    for line in proc.stderr:  # the first configuration is measured: bundles are being written
        if line.startswith("fp32:"):
            break
    time.sleep(1.0)
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == (130 if sig == "SIGINT" else 143), err
    assert "Traceback" not in err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
