"""Every bundle carries what its honesty checks need, and compress decides robustly: export, quantize and compress record ``data_stats`` from the frames they see
(or say loudly that the checks are off); a compressed student run on another sensor's frames
(GelSight Wedge) is flagged ``out_of_distribution``; a student too far from its teacher is not
written as the result.

Real torch training, real ONNX Runtime, real Wedge video frames.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from tactile_force.edge import (
    ContactGate,
    Flags,
    ForceRuntime,
    OnnxForceModel,
    RuntimeOptions,
    Sensor,
    load_bundle,
)
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.synthetic import DatasetOptions, generate_dataset
from tactile_force.export import ModelSpec, save_checkpoint
from tactile_force.export.compress import CompressOptions, Rung, compress_model
from tactile_force.export.training import Frames, TrainOptions, train_network

from tests.conftest import ListSource, shared_data


@pytest.fixture(scope="module")
def setup(tmp_path_factory):
    """A tiny trained teacher checkpoint and 40 unlabelled synthetic DIGIT frames."""
    root = tmp_path_factory.mktemp("honesty")
    unl = generate_dataset(root / "unlabelled", DatasetOptions(n=40, seed=31, progress=False)).root
    teach = generate_dataset(root / "teacher_data", DatasetOptions(n=48, seed=32, progress=False)).root
    from tactile_force.edge import AuthorsDataset

    ds = AuthorsDataset(teach)
    f = Frames({"rgb": np.stack([ds.load(n).frame for n in ds.ids])}, ds.forces().astype(np.float32))
    spec = ModelSpec("rgbmod", 0.125, 1 / 8)
    res = train_network(spec, f, f, TrainOptions(epochs=1, batch=16, seed=0, threads=2))
    return root, Path(unl), Path(teach), save_checkpoint(root / "teacher.pth", res.model, spec)


def _compress(setup, out, **kw):
    _, unl, _, teacher = setup
    known = {k: v for k, v in kw.items() if k in CompressOptions.__dataclass_fields__}  # c1733e6 had no limit
    return compress_model(CompressOptions(teacher=teacher, frames=[unl / "images"], out=out,
                                          ladder=(Rung(0.125, 8),), epochs=1, budget_ms=1e6, latency_runs=10,
                                          calibration_frames=20, threads=2, **known))


def _wedge_contact_frames() -> tuple[list[tuple[np.ndarray, list[np.ndarray], list[float]]], int]:
    """Per Wedge grasp: (its no-contact frame 0, its frames at 11-14 N, their forces)."""
    shared_data("gelsight_wedge_grasps")
    from benchmarks.harness.data import wedge_grasps

    out, n = [], 0
    for _, frames, forces in wedge_grasps():
        sel = [k for k, x in enumerate(forces) if 11.0 <= x <= 14.0]
        if sel:
            out.append((frames[0], [frames[k] for k in sel], [forces[k] for k in sel]))
            n += len(sel)
    return out, n


def test_compressed_student_records_data_stats_and_flags_wedge_frames(setup, tmp_path):
    result = _compress(setup, tmp_path / "out", max_vs_teacher_re=math.inf)
    assert result.bundle is not None
    grasps, n = _wedge_contact_frames()
    assert n >= 40
    model = OnnxForceModel(result.bundle.path)
    readings = []
    for bg, frames, forces in grasps:
        gate = ContactGate()
        gate.capture_background([bg])
        rt = ForceRuntime([Sensor("wedge", ListSource(frames, forces), gate)], model, RuntimeOptions(deadline_ms=1e9))
        rt.run(on_reading=readings.append)
    model.close()
    judged = Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.BACKGROUND_MISMATCH | Flags.OUT_OF_DISTRIBUTION
    silent = [r for r in readings if math.isfinite(r.force_n) and not (r.flags & judged)]
    assert len(readings) == n and not silent, f"{len(silent)} of {n} Wedge readings at 11-14 N unflagged"
    assert sum(1 for r in readings if Flags.OUT_OF_DISTRIBUTION in r.flags) >= n // 2
    m = load_bundle(result.bundle.path).manifest
    assert m.data_stats is not None and m.data_stats.frames == 40 and not m.data_stats.contact_measured


def test_export_without_frames_says_the_checks_are_off_and_with_frames_records_them(setup, tmp_path, capsys):
    _, _, teach, teacher = setup
    assert cli_main(["export", str(teacher), "--out", str(tmp_path / "blind")]) == 0
    err = capsys.readouterr().err
    assert "WARNING" in err and "checks are OFF" in err
    m = load_bundle(tmp_path / "blind").manifest
    assert m.data_stats is None and "no --parity-data" in m.data_stats_missing
    assert cli_main(["bundle", "show", str(tmp_path / "blind")]) == 0
    assert "out-of-distribution and contact-size checks OFF" in capsys.readouterr().out

    assert cli_main(["export", str(teacher), "--out", str(tmp_path / "seen"), "--parity-data", str(teach)]) == 0
    m = load_bundle(tmp_path / "seen").manifest
    assert m.data_stats is not None and m.data_stats.frames == 32 and not m.data_stats_missing
    assert cli_main(["bundle", "show", str(tmp_path / "seen")]) == 0
    assert "out-of-distribution check on" in capsys.readouterr().out


def test_quantize_records_data_stats_from_its_calibration_frames(setup, tmp_path, capsys):
    _, unl, teach, teacher = setup
    assert cli_main(["export", str(teacher), "--out", str(tmp_path / "fp32")]) == 0
    assert cli_main(["quantize", str(tmp_path / "fp32"), "--out", str(tmp_path / "int8"), "--calib", str(teach),
                     "--min-frames", "5", "--max-frames", "20"]) == 0
    m = load_bundle(tmp_path / "int8").manifest
    assert m.data_stats is not None and m.data_stats.frames == 20 and not m.data_stats_missing
    assert cli_main(["quantize", str(tmp_path / "fp32"), "--out", str(tmp_path / "fp16"), "--mode", "fp16"]) == 0
    assert "checks are OFF" in capsys.readouterr().err
    m = load_bundle(tmp_path / "fp16").manifest
    assert m.data_stats is None and "quantize saw no" in m.data_stats_missing


def test_a_student_too_far_from_its_teacher_is_not_written(setup, tmp_path, capsys):
    _, unl, _, teacher = setup
    out = tmp_path / "out"
    rc = cli_main(["compress", str(teacher), "--frames", str(unl / "images"), "--out", str(out), "--ladder",
                   "0.125x8", "--epochs", "1", "--budget-ms", "1e6", "--max-frames", "40",
                   "--max-vs-teacher-re", "1e-6"])
    captured = capsys.readouterr()
    assert rc == 1 and not (out / "bundle").exists()
    assert "rgbmod-w0.125-s8: p99 " in captured.out and "vs teacher RE" in captured.out and "above the 1e-06 RE limit" in captured.out
    assert "max-vs-teacher-re" in captured.err and "Traceback" not in captured.err
    summary = json.loads((out / "compress.json").read_text())
    assert summary["chosen"] is None and summary["students"][0]["within_error_limit"] is False


def test_compress_latency_is_the_median_of_block_p99s(setup, tmp_path):
    result = _compress(setup, tmp_path / "out", max_vs_teacher_re=math.inf, latency_blocks=5)
    rec = result.students[0]
    assert len(rec["p99_blocks_ms"]) == 5
    assert rec["p99_ms"] == pytest.approx(float(np.median(rec["p99_blocks_ms"])), abs=1e-3)
