"""Distil a trained model into compact RGBmod students and keep the best one within a latency budget.

    compress_model(CompressOptions(teacher="model.pth", frames=["frames/"], out="compressed"))

Steps (``tactile-force compress``):

1. read the UNLABELLED frames (plain image folders, videos, the authors' layout, ``record``
   output) and, if given, labelled frames (authors' layout);
2. run the teacher (a checkpoint, authors' format or ours, or an fp32 bundle through ONNX
   Runtime) once on all of them; its outputs are cached in ``OUT/work`` under a key made of
   the teacher's sha256 and the frames' content;
3. train each student of the ladder (width x input scale 1/k x residual blocks per stage:
   narrower, smaller-input and fewer-blocks students) on the teacher's outputs with
   sensor-variability augmentation (:mod:`.training`, the same loop as the reference recipe);
   half of the labelled frames (when there are >= 10) are mixed in with their labels, the
   other half are kept for evaluation. Each finished student is saved in ``OUT/work``
   (checkpoint + record): Ctrl-C keeps them and a rerun resumes with the next student;
4. export each student, quantize it to int8 (static, calibrated on the same unlabelled
   frames it was distilled on), measure its p99 on this host through the runtime's model
   (:class:`OnnxForceModel`, batch 2, one thread), and its error against the teacher on
   held-out unlabelled frames and against the held-out labels;
5. time every student in round-robin blocks (p99 = the median of its block p99s), order them by
   that p99 and record what each step down costs in error (:func:`error_steps`: RE vs the
   teacher and vs the labels, against the next costlier student or the teacher), then write
   the most accurate student (vs the teacher) whose p99 fits the budget and whose error vs
   the teacher is within ``max_vs_teacher_re`` to ``OUT/bundle``; none: no bundle (the CLI
   exits 1 with the table). Its manifest records the teacher, both errors, the latency, the
   host and ``data_stats`` of the frames compress saw (the runtime's honesty checks).

Deterministic for a seed on a given machine; CPU only. This module runs the steps; the
ladder, options and result are in :mod:`.compress_options`, the frames and the teacher in
:mod:`.compress_inputs`, a student's bundle, timing and error steps in
:mod:`.compress_students`, the result bundle in :mod:`.compress_report`.
"""

from __future__ import annotations

import hashlib
import json
import math
import shutil
from dataclasses import asdict
from pathlib import Path

import numpy as np
from tactile_force.edge.fitting.data_stats import frames_data_stats
from tactile_force.edge.frames import FRAME_SHAPE

from .calibration import CalibrationData
from .checkpoint import save_checkpoint
from .compress_inputs import IMAGE_SUFFIXES as IMAGE_SUFFIXES  # importable from here as before
from .compress_inputs import VIDEO_SUFFIXES as VIDEO_SUFFIXES
from .compress_inputs import Teacher as Teacher
from .compress_inputs import frames_digest, load_teacher, read_frames, read_labels, teacher_outputs
from .compress_options import DEFAULT_LADDER, CompressError, CompressOptions, CompressResult, Rung, parse_ladder
from .compress_report import host_description, write_final, write_json
from .compress_students import error_steps, finish_student, time_students
from .training import Frames, TrainOptions, train_network


def compress_model(o: CompressOptions) -> CompressResult:
    """Run the whole compression (see the module docstring); resumes from ``o.out/work``."""
    if not o.ladder:
        raise CompressError("ladder: no students given")
    if not (math.isfinite(o.budget_ms) and o.budget_ms > 0):
        raise CompressError(f"--budget-ms {o.budget_ms}: expected a positive number of milliseconds")
    if not (o.max_vs_teacher_re > 0) or math.isnan(o.max_vs_teacher_re):
        raise CompressError(f"--max-vs-teacher-re {o.max_vs_teacher_re}: expected a number > 0 (RE against the "
                            "teacher, e.g. 0.25)")
    if o.latency_runs < 1 or o.latency_blocks < 1:
        raise CompressError(f"latency_runs {o.latency_runs}, latency_blocks {o.latency_blocks}: expected >= 1")
    if not 0 < o.val_share < 0.5:
        raise CompressError(f"val_share {o.val_share}: expected 0 < share < 0.5")
    for r in o.ladder:
        if not (0 < r.width <= 4) or r.k < 1 or FRAME_SHAPE[0] % r.k or FRAME_SHAPE[1] % r.k:
            raise CompressError(f"ladder {r.width:g}x{r.k}: expected 0 < width <= 4 and k dividing 320 and 240")
    # the training options are checked here too (threads), before any work
    topt = TrainOptions(epochs=o.epochs, lr=o.lr, batch=o.batch, seed=o.seed, threads=o.threads, augment=o.augment)
    out = Path(o.out)
    work = out / "work"
    show = o.show_progress
    teacher = load_teacher(o.teacher)
    frames, frames_desc = read_frames(list(o.frames), o.max_frames)
    if len(frames) < 20:
        raise CompressError(f"--frames: only {len(frames)} frame(s); at least 20 are needed (a few thousand covering "
                            "light to firm presses is better)")
    lab_frames, lab_forces = (read_labels(o.labels) if o.labels is not None
                              else (np.empty((0, *FRAME_SHAPE), np.uint8), np.empty(0)))
    # What the student sees, for the runtime's honesty checks (out-of-distribution, contact size).
    data_stats = frames_data_stats(list(frames) + list(lab_frames), o.background,
                                   f"{len(frames) + len(lab_frames)} compress frames ({frames_desc})", "compress")
    work.mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256((teacher.sha256 + frames_digest(frames)).encode()).hexdigest()
    t_frames = teacher_outputs(teacher, frames, work, key, show)

    rng = np.random.default_rng(o.seed)
    order = rng.permutation(len(frames))
    n_val = max(2, round(o.val_share * len(frames)))
    val_idx, tr_idx = np.sort(order[:n_val]), np.sort(order[n_val:])
    lab_order = rng.permutation(len(lab_forces))
    if len(lab_forces) >= 10:
        lab_tr, lab_ev = np.sort(lab_order[: len(lab_order) // 2]), np.sort(lab_order[len(lab_order) // 2:])
    else:
        lab_tr, lab_ev = np.empty(0, int), np.sort(lab_order)
    train = Frames({"rgb": np.concatenate([frames[tr_idx], lab_frames[lab_tr]])},
                   np.concatenate([t_frames[tr_idx], lab_forces[lab_tr]]).astype(np.float32))
    val = Frames({"rgb": frames[val_idx]}, t_frames[val_idx])
    lab_key = frames_digest(lab_frames, lab_forces) if len(lab_forces) else ""
    run_key = hashlib.sha256(json.dumps([key, lab_key, o.seed, o.val_share, asdict(topt)],
                                        default=str).encode()).hexdigest()[:16]
    calib = CalibrationData({"rgb": train.inputs["rgb"][
        np.linspace(0, len(train) - 1, min(o.calibration_frames, len(train))).round().astype(int)]},
        None, f"{len(train)} distillation frames ({frames_desc})", [])
    calib.ids = [str(i) for i in range(len(calib.inputs["rgb"]))]
    val_data = CalibrationData({"rgb": val.inputs["rgb"]}, None, "held-out unlabelled frames",
                               [str(i) for i in range(len(val))])
    lab_ev_data = (CalibrationData({"rgb": lab_frames[lab_ev]}, lab_forces[lab_ev], f"{o.labels} (held-out half)",
                                   [str(i) for i in lab_ev]) if len(lab_ev) else None)

    from tqdm import tqdm

    records: list[dict] = []
    for rung in tqdm(o.ladder, desc="students", unit="student", disable=not show):
        sdir = work / f"{rung.name}-{run_key}"
        rec_path = sdir / "record.json"
        if rec_path.is_file():
            rec = json.loads(rec_path.read_text())
            rec["resumed"] = True
        else:
            sdir.mkdir(parents=True, exist_ok=True)
            res = train_network(rung.spec, train, val, topt, show_progress=show, desc=rung.name)
            save_checkpoint(sdir / "model.pth", res.model, rung.spec,
                            extra={"trained_on": f"distilled from {teacher.description} on {frames_desc}"})
            rec = {"name": rung.name, "width": rung.width, "k": rung.k, "blocks": list(rung.blocks),
                   "best_epoch": res.best_epoch,
                   "train_seconds": round(res.seconds, 1), "epochs": o.epochs, "resumed": False}
            write_json(rec_path, rec)
        if "vs_teacher" not in rec:
            rec.update(finish_student(sdir, rung, teacher, calib, val_data, val.targets, lab_ev_data, o))
            write_json(rec_path, {k: v for k, v in rec.items() if k != "resumed"})
        records.append(rec)
        if o.on_student is not None:
            o.on_student(rec)

    time_students(records, o.latency_runs, o.latency_blocks)
    error_steps(records)
    fits = [r for r in records if r["p99_ms"] <= o.budget_ms]
    for rec in records:
        rec["within_error_limit"] = bool(rec["vs_teacher"]["re_mean"] <= o.max_vs_teacher_re)
    good = [r for r in fits if r["within_error_limit"]]
    chosen = min(good, key=lambda r: r["vs_teacher"]["re_mean"]) if good else None
    bundle = None
    if chosen is not None:
        bundle = write_final(out / "bundle", chosen, teacher, frames_desc, len(frames), o, records, data_stats)
    elif (out / "bundle" / "model.json").is_file():  # an earlier run's choice must not look like this run's
        shutil.rmtree(out / "bundle")
    summary = out / "compress.json"
    write_json(summary, {"teacher": {"source": teacher.source, "kind": teacher.kind, "sha256": teacher.sha256},
                          "frames": frames_desc, "labels": str(o.labels) if o.labels else None,
                          "budget_ms": o.budget_ms, "max_vs_teacher_re": o.max_vs_teacher_re,
                          "seed": o.seed, "host": host_description(),
                          "chosen": chosen["name"] if chosen else None, "students": records})
    return CompressResult(bundle, chosen, records, summary)


__all__ = [
    "DEFAULT_LADDER",
    "CompressError",
    "CompressOptions",
    "CompressResult",
    "Rung",
    "compress_model",
    "error_steps",
    "load_teacher",
    "parse_ladder",
    "read_frames",
]
