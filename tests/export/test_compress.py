"""tactile-force compress end to end on a small teacher and a few hundred synthetic frames."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from tactile_force.edge import load_bundle
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.runtime import ForceRuntime, Sensor
from tactile_force.edge.sources import ReplayFolderSource
from tactile_force.edge.synthetic import DatasetOptions, VirtualDigit, VirtualDigitOptions, generate_dataset
from tactile_force.export import ModelSpec, save_checkpoint
from tactile_force.export.compress import CompressOptions, Rung, compress_model
from tactile_force.export.training import Frames, TrainOptions, train_network

LADDER = (Rung(0.125, 8), Rung(0.25, 8, (1, 1, 1, 1)))  # narrower / fewer blocks per stage


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    root = tmp_path_factory.mktemp("compress")
    unl = generate_dataset(root / "unlabelled", DatasetOptions(n=200, seed=21, progress=False)).root
    lab = generate_dataset(root / "labelled", DatasetOptions(n=12, seed=22, progress=False)).root
    teach_data = generate_dataset(root / "teacher_data", DatasetOptions(n=96, seed=23, progress=False)).root
    from tactile_force.edge import AuthorsDataset

    ds = AuthorsDataset(teach_data)
    rgb = np.stack([ds.load(n).frame for n in ds.ids])
    f = Frames({"rgb": rgb}, ds.forces().astype(np.float32))
    spec = ModelSpec("rgbmod", 0.125, 1 / 8)
    res = train_network(spec, f, f, TrainOptions(epochs=3, batch=16, seed=0, threads=2))
    teacher = save_checkpoint(root / "teacher.pth", res.model, spec)
    return root, Path(unl), Path(lab), teacher


def _options(setup, out, **kw):
    root, unl, lab, teacher = setup
    kw.setdefault("max_vs_teacher_re", float("inf"))  # 2-epoch students: the resume logic is tested, not accuracy
    return CompressOptions(teacher=teacher, frames=[unl / "images"], labels=lab, out=out, ladder=LADDER, epochs=2,
                           budget_ms=1e6, latency_runs=20, calibration_frames=40, threads=2, **kw)


def test_interrupt_keeps_finished_students_and_a_rerun_resumes(setup, tmp_path):
    out = tmp_path / "out"
    seen = []

    def stop_after_first(rec):
        seen.append(rec["name"])
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        compress_model(_options(setup, out, on_student=stop_after_first))
    assert seen == ["rgbmod-w0.125-s8"]
    records = sorted((out / "work").glob("*/record.json"))
    assert len(records) == 1 and "rgbmod-w0.125-s8" in records[0].parent.name
    cache = next((out / "work").glob("teacher-*.npy"))
    stamp = cache.stat().st_mtime_ns
    ckpt_stamp = (records[0].parent / "model.pth").stat().st_mtime_ns
    assert not (out / "bundle").exists()

    result = compress_model(_options(setup, out))
    assert [r["name"] for r in result.students] == ["rgbmod-w0.125-s8", "rgbmod-w0.25-s8-b1111"]
    assert [load_bundle(r["bundle"]).manifest.architecture.blocks for r in result.students] == [[2, 2, 2, 2],
                                                                                                 [1, 1, 1, 1]]
    # the error each step down the ladder (by measured p99) costs, against the labels too
    first, second = sorted(result.students, key=lambda r: -r["p99_ms"])
    assert first["step"]["from"] == "teacher" and second["step"]["from"] == first["name"]
    assert first["step"]["vs_teacher_re"] == pytest.approx(first["vs_teacher"]["re_mean"])
    assert second["step"]["vs_teacher_re"] == pytest.approx(second["vs_teacher"]["re_mean"]
                                                            - first["vs_teacher"]["re_mean"])
    assert first["step"]["vs_labels_re"] == pytest.approx(first["vs_labels"]["re_mean"]
                                                          - first["teacher_vs_labels"]["re_mean"])
    assert [r["resumed"] for r in result.students] == [True, False]
    assert cache.stat().st_mtime_ns == stamp  # teacher outputs came from the cache
    assert (records[0].parent / "model.pth").stat().st_mtime_ns == ckpt_stamp  # not retrained

    b = load_bundle(out / "bundle")  # verifies the hash
    m = b.manifest
    assert m.precision.value == "int8-static" and m.variant.value == "rgbmod"
    assert m.error.vs_teacher is not None and m.error.vs_truth is not None
    # the interval is fitted on the held-out labelled half (6 frames: too few for 0.90, so 'unknown')
    assert m.interval is not None and m.interval.model_sha256 == m.sha256 and m.interval.n == m.error.vs_truth.n
    assert not m.interval.known and "held-out half" in m.interval.data
    import hashlib

    assert m.provenance.teacher["sha256"] == hashlib.sha256(Path(setup[3]).read_bytes()).hexdigest()
    assert m.provenance.host and m.provenance.extra["p99_ms_batch2"] > 0
    chosen = min(result.students, key=lambda r: r["vs_teacher"]["re_mean"])
    assert result.chosen["name"] == chosen["name"]
    summary = json.loads(result.summary_path.read_text())
    assert summary["chosen"] == chosen["name"] and len(summary["students"]) == 2
    assert all("step" in r and "blocks" in r for r in summary["students"])

    # the written bundle runs in the runtime on labelled frames
    _, _, lab, _ = setup
    gate = ContactGate()
    gate.capture_background([VirtualDigit(VirtualDigitOptions()).render(None, 0.0, led_gain=(1.0, 1.0, 1.0)).frame])
    rt = ForceRuntime([Sensor("s", ReplayFolderSource(lab), gate)], OnnxForceModel(out / "bundle"))
    stats = rt.run()
    assert stats.readings == 12 and stats.inferred > 0


def test_budget_nobody_fits_writes_no_bundle(setup, tmp_path):
    out = tmp_path / "out"
    o = _options(setup, out)
    o.ladder = (Rung(0.125, 8),)
    o.budget_ms = 1e-6
    o.epochs = 1
    result = compress_model(o)
    assert result.bundle is None and result.chosen is None and not (out / "bundle").exists()
    assert len(result.students) == 1 and result.students[0]["p99_ms"] > 1e-6


def test_cli_bad_input_exits_2(setup, tmp_path, capsys):
    _, unl, _, teacher = setup
    assert cli_main(["compress", str(teacher), "--frames", str(tmp_path / "none"), "--out", str(tmp_path / "o")]) == 2
    assert "not found" in capsys.readouterr().err
    few = tmp_path / "few"
    few.mkdir()
    import shutil

    for p in sorted((unl / "images").iterdir())[:5]:
        shutil.copy(p, few / p.name)
    assert cli_main(["compress", str(teacher), "--frames", str(few), "--out", str(tmp_path / "o")]) == 2
    assert "at least 20" in capsys.readouterr().err
    import cv2

    wrong = tmp_path / "wrong"
    wrong.mkdir()
    cv2.imwrite(str(wrong / "0.png"), np.zeros((240, 320, 3), np.uint8))
    assert cli_main(["compress", str(teacher), "--frames", str(wrong), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "transposed" in err and "Traceback" not in err
    assert cli_main(["compress", str(tmp_path / "nope.pth"), "--frames", str(unl), "--out", str(tmp_path / "o")]) == 2
    assert cli_main(["compress", str(teacher), "--frames", str(unl), "--out", str(tmp_path / "o"),
                     "--ladder", "0.25by4"]) == 2


def test_cli_with_default_threads_ends_normally(tmp_path):
    """The CLI end to end with torch's default threads (all cores), in its own process: a native
    crash there takes the process down. 60 frames leave 51 training frames, one odd-sized batch:
    on a 2-core host the width-0.125 student's training used to corrupt the heap every time."""
    import subprocess
    import sys

    from tactile_force.edge import AuthorsDataset

    data = generate_dataset(tmp_path / "frames", DatasetOptions(n=60, seed=0, progress=False)).root
    ds = AuthorsDataset(data)
    f = Frames({"rgb": np.stack([ds.load(n).frame for n in ds.ids])}, ds.forces().astype(np.float32))
    spec = ModelSpec("rgbmod", 0.125, 1 / 8)
    teacher = save_checkpoint(tmp_path / "teacher.pth", train_network(
        spec, f, f, TrainOptions(epochs=1, batch=16, seed=0, threads=1)).model, spec)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "compress", str(teacher),
                          "--frames", str(Path(data) / "images"), "--out", str(out), "--ladder", "0.125x8",
                          "--epochs", "1", "--budget-ms", "1e6", "--max-vs-teacher-re", "1e9"],
                         capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-2000:]
    assert load_bundle(out / "bundle").manifest.precision.value == "int8-static"
    # a finished result is replaced only with --force; a folder of other files never; SIGTERM: 143
    argv = [sys.executable, "-m", "tactile_force.edge.cli", "compress", str(teacher), "--frames",
            str(Path(data) / "images"), "--ladder", "0.125x8", "--epochs", "1", "--budget-ms", "1e6",
            "--max-vs-teacher-re", "1e9"]
    again = subprocess.run([*argv, "--out", str(out)], capture_output=True, text=True)
    assert again.returncode == 2 and "--force" in again.stderr and "Traceback" not in again.stderr
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep")
    other = subprocess.run([*argv, "--out", str(mine), "--force"], capture_output=True, text=True)
    assert other.returncode == 2 and "notes.txt" in other.stderr and (mine / "notes.txt").read_text() == "keep"
    import signal
    import time

    fresh = tmp_path / "fresh"
    proc = subprocess.Popen([*argv, "--out", str(fresh)], stderr=subprocess.PIPE, text=True)
    end = time.monotonic() + 120
    while time.monotonic() < end and not (fresh / "work").is_dir():
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err[-2000:]
    assert not (fresh / "compress.json").exists() and not (fresh / "bundle").exists()


def test_threads_is_validated_before_any_work(tmp_path, capsys):
    out = tmp_path / "o"
    assert cli_main(["compress", str(tmp_path / "t.pth"), "--frames", str(tmp_path), "--out", str(out),
                     "--threads", "0"]) == 2
    err = capsys.readouterr().err
    assert "--threads" in err and "expected an integer in [1, 1024]" in err and "Traceback" not in err
    from tactile_force.edge.errors import OptionsError

    with pytest.raises(OptionsError, match="threads"):
        compress_model(CompressOptions(teacher=tmp_path / "t.pth", frames=[tmp_path], out=out, threads=-1))
    assert not out.exists()


def test_a_second_compress_into_the_same_out_is_refused_while_one_runs(tmp_path, capsys):
    from tactile_force.edge.files.claim import OutputClaim

    out = tmp_path / "c"
    argv = ["compress", str(tmp_path / "t.pth"), "--frames", str(tmp_path / "none"), "--out", str(out)]
    with OutputClaim(out, "compress", inside=True):  # a compress at work there
        assert cli_main(argv) == 2
        assert f"--out {out}: 'tactile-force compress' (pid" in capsys.readouterr().err
    assert cli_main(argv) == 2 and "not found" in capsys.readouterr().err  # refused for its own reason
    assert not out.exists()  # a refused run leaves no empty --out behind
