"""What ``compress`` writes: the chosen student as the result bundle (its manifest: teacher,
errors, interval, latency, host, ``data_stats``), JSON records written whole, and the host
the latency figures were made on (export/compress.py runs it)."""

from __future__ import annotations

import copy
import json
import os
import platform
import time
from pathlib import Path

from tactile_force.edge.bundle.data_stats import DataStats
from tactile_force.edge.bundle.manifest import ErrorFigures, ErrorReport
from tactile_force.edge.bundle.store import Bundle, load_bundle, write_bundle
from tactile_force.edge.fitting.interval import fit_interval

from .compress_inputs import Teacher
from .compress_options import CompressOptions


def host_description() -> str:
    """CPU model, logical cores and OS of this host (recorded with latency figures)."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} logical cores, {platform.system()} {platform.release()}"


def write_json(path: Path, obj: object) -> None:
    from tactile_force.edge.files.atomic import staged_file

    with staged_file(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2, default=float))


def write_final(dest: Path, chosen: dict, teacher: Teacher, frames_desc: str, n_frames: int, o: CompressOptions,
                records: list[dict], data_stats: DataStats) -> Bundle:
    src = load_bundle(chosen["bundle"])
    m = copy.deepcopy(src.manifest)
    m.data_stats, m.data_stats_missing = data_stats, ""
    m.name = f"{chosen['name']}-int8-distilled"
    vt = chosen["vs_teacher"]
    vl = chosen.get("vs_labels")
    m.error = ErrorReport(
        data=(f"{o.labels} (held-out half of the labelled frames)" if vl else
              f"held-out unlabelled frames ({vt['n']}) vs the teacher"),
        frames=vl["n"] if vl else vt["n"],
        vs_truth=ErrorFigures(**vl) if vl else None,
        vs_teacher=ErrorFigures(**vt))
    # every reading's error bar: split conformal on the held-out labelled frames (edge/bundle/interval.py);
    # without labels none (an interval against the teacher would not bound the true force)
    pred, truth = chosen.get("labels_pred_n"), chosen.get("labels_truth_n")
    m.interval = (fit_interval(pred, truth, model_sha256=src.manifest.sha256,
                               data=f"{o.labels} (held-out half of the labelled frames, {len(pred)})")
                  if pred and truth else None)
    m.provenance.trained_on = f"distilled from the teacher on {n_frames} unlabelled frames: {frames_desc}"
    m.provenance.teacher = {"source": teacher.source, "kind": teacher.kind, "sha256": teacher.sha256,
                            "description": teacher.description}
    m.provenance.host = host_description()
    m.provenance.extra = {"p99_ms_batch2": round(float(chosen["p99_ms"]), 4), "budget_ms": o.budget_ms,
                          "seed": o.seed, "epochs": o.epochs, "student": chosen["name"],
                          "ladder": ",".join(f"{r['name']}:{r['p99_ms']:.3f}ms" for r in records),
                          "vs_teacher_re_mean": vt["re_mean"]}
    m.provenance.note = (f"Distilled by 'tactile-force compress' ({time.strftime('%Y-%m-%d')}); "
                         "student-vs-teacher error on held-out unlabelled frames in error.vs_teacher.")
    return write_bundle(dest, src.onnx_path.read_bytes(), m, overwrite=True)
