"""One trained ``compress`` student made a bundle and measured (export, int8 quantization, error
against the teacher and the labels), every student timed round-robin on this host, and what
each step down the ladder costs in error (export/compress.py runs it)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from tactile_force.edge.data.metrics import error_stats

from .calibration import CalibrationData
from .compress_inputs import Teacher
from .compress_options import CompressOptions, Rung
from .onnx_export import ExportOptions, export_bundle, ort_session, run_ort
from .quantize import QuantizeOptions, quantize_bundle


def _figures(pred: np.ndarray, ref: np.ndarray) -> dict:
    return error_stats(pred, ref).as_dict()  # the fields of manifest.ErrorFigures


def finish_student(sdir: Path, rung: Rung, teacher: Teacher, calib: CalibrationData, val_data: CalibrationData,
                   val_teacher: np.ndarray, lab_ev: CalibrationData | None, o: CompressOptions) -> dict:
    """Export, int8-quantize, evaluate and time one trained student."""
    fp32 = export_bundle(sdir / "model.pth", sdir / "fp32", ExportOptions(
        parity_data=val_data.subset(16), name=f"{rung.name}-fp32", overwrite=True,
        trained_on=f"distilled from {teacher.description}"))
    int8 = quantize_bundle(fp32, sdir / "int8", QuantizeOptions(mode="int8-static", name=f"{rung.name}-int8",
                                                                overwrite=True), calibration=calib, eval_data=val_data)
    sess = ort_session(int8.onnx_path.read_bytes(), threads=max(1, os.cpu_count() or 1))
    m = int8.manifest  # compact students read frames reduced as the runtime reduces them
    rec: dict = {"vs_teacher": _figures(run_ort(sess, val_data.for_manifest(m)), val_teacher)}
    if lab_ev is not None and lab_ev.forces is not None:
        pred = run_ort(sess, lab_ev.for_manifest(m))
        rec["vs_labels"] = _figures(pred, lab_ev.forces)
        # the held-out labelled frames: the final bundle's interval is fitted on them (write_final)
        rec["labels_pred_n"] = [float(v) for v in pred]
        rec["labels_truth_n"] = [float(v) for v in lab_ev.forces]
        rec["teacher_vs_labels"] = _figures(teacher.predict(lab_ev.inputs["rgb"]), lab_ev.forces)
    rec["gmacs"] = int8.manifest.architecture.gmacs
    rec["bundle"] = str(sdir / "int8")
    return rec


def time_students(records: list[dict], runs: int, blocks: int) -> None:
    """Set each record's ``p99_ms`` to the median of ``blocks`` block p99s (ms) of a batch-2
    predict (``runs`` calls a block, one thread), the blocks taken round-robin over the
    students so that machine noise falls on all of them alike; ``p99_blocks_ms`` keeps them."""
    from tactile_force.edge.model.ladder import measure_p99_ms
    from tactile_force.edge.model.onnx_model import OnnxForceModel

    models = [OnnxForceModel(r["bundle"], threads=1) for r in records]
    try:
        per: list[list[float]] = [[] for _ in records]
        for _ in range(blocks):
            for k, m in enumerate(models):
                per[k].append(measure_p99_ms(m, runs=runs))
    finally:
        for m in models:
            m.close()
    for r, p in zip(records, per):
        r["p99_ms"] = float(np.median(p))
        r["p99_blocks_ms"] = [round(v, 4) for v in p]


def error_steps(records: list[dict]) -> list[dict]:
    """What each step down the ladder costs in error, cheapest last: ``records`` ordered by
    measured p99 (costliest first); each gets ``step`` = {"from": the next costlier student's
    name, or "teacher" for the costliest, "vs_teacher_re": its RE vs the teacher minus that
    one's (the teacher's own is 0), "vs_labels_re": the same against the labels (the teacher's
    RE vs the labels for the first step), or None without labels}. Returns the ordered list."""
    ordered = sorted(records, key=lambda r: -float(r["p99_ms"]))
    prev: dict | None = None
    for rec in ordered:
        vl = rec.get("vs_labels")
        if prev is None:
            base_t, base_l = 0.0, rec.get("teacher_vs_labels", {}).get("re_mean") if vl else None
        else:
            base_t, base_l = prev["vs_teacher"]["re_mean"], prev.get("vs_labels", {}).get("re_mean")
        rec["step"] = {"from": prev["name"] if prev is not None else "teacher",
                       "vs_teacher_re": float(rec["vs_teacher"]["re_mean"] - base_t),
                       "vs_labels_re": (float(vl["re_mean"] - base_l) if vl is not None and base_l is not None
                                        else None)}
        prev = rec
    return ordered
