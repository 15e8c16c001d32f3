"""Distilled students against their teacher and against the same students trained with labels.

    python -m benchmarks.distill_study                  # writes docs/benchmarks/distillation.md
    python -m benchmarks.distill_study --teacher 0.5x4 --teacher-epochs 8 --student-epochs 12

Teacher: an RGBmod trained WITH labels by the reference recipe on the reference dataset's
S1 train indenters (benchmarks.reference: synthetic, n=4000, seed 0). Students: distilled
by ``tactile-force compress``'s code on UNLABELLED synthetic frames of another seed
(train indenters only, so the test indenters stay unseen); for comparison the same student
configs trained with labels by the reference recipe. Everything is evaluated as int8
bundles (the teacher as fp32) on the S1 held-out test indenters; p99 of a batch-2 predict,
one thread, on this host.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .frames import CACHE, REPO

OUT = REPO / "docs" / "benchmarks" / "distillation.md"
ROOT = CACHE / "distill"


def _rung(text: str):
    from tactile_force.export.compress import parse_ladder

    return parse_ladder(text)


def _frames(data, idx: np.ndarray):
    from tactile_force.export.training import Frames

    return Frames({"rgb": data.rgb[idx]}, data.force[idx])


def _train_labelled(name: str, spec, data, epochs: int, seed: int = 0) -> Path:
    """Reference recipe (labels, no augmentation): checkpoint path, cached."""
    from tactile_force.export import save_checkpoint
    from tactile_force.export.training import TrainOptions, train_network

    ckpt = ROOT / name / "model.pth"
    if ckpt.is_file():
        return ckpt

    def log(e) -> None:
        print(f"[{name}] epoch {e.epoch}/{epochs}: train L1 {e.train_l1:.3f} N, val RE {e.val_re:.3f} "
              f"({e.seconds:.0f} s)", flush=True)

    res = train_network(spec, _frames(data, data.select("train")), _frames(data, data.select("val")),
                        TrainOptions(epochs=epochs, seed=seed), log=log)
    save_checkpoint(ckpt, res.model, spec, extra={"trained_on": "reference dataset S1 train (labels)",
                                                  "best_epoch": res.best_epoch})
    (ROOT / name / "train.json").write_text(json.dumps({"best_epoch": res.best_epoch, "seconds": res.seconds,
                                                       "epochs": epochs}))
    return ckpt


def _bundles(ckpt: Path, data, int8: bool) -> Path:
    from tactile_force.export import ExportOptions, QuantizeOptions, export_bundle, quantize_bundle

    from .reference import TrainConfig, calibration_data

    cfg = TrainConfig("rgbmod", 1.0, 1)
    fp32 = ckpt.parent / "fp32"
    if not (fp32 / "model.json").is_file():
        export_bundle(ckpt, fp32, ExportOptions(parity_data=calibration_data(cfg, data, "test", 16), overwrite=True))
    if not int8:
        return fp32
    q = ckpt.parent / "int8"
    if not (q / "model.json").is_file():
        quantize_bundle(fp32, q, QuantizeOptions(mode="int8-static", overwrite=True),
                        calibration=calibration_data(cfg, data, "train", 200))
    return q


def _evaluate(bundle: Path, data) -> tuple[dict, float]:
    from tactile_force.edge.data.metrics import error_stats
    from tactile_force.edge.model.onnx_model import OnnxForceModel, measure_p99_ms

    model = OnnxForceModel(bundle, threads=1)
    te = data.select("test")
    pred = np.concatenate([model.predict(data.rgb[te[i:i + 2]]) for i in range(0, len(te), 2)])
    return error_stats(pred, data.force[te]).as_dict(), measure_p99_ms(model, runs=300)


def _interleaved_latency(paths: dict[str, Path], rounds: int = 20, calls: int = 100) -> dict[str, tuple[float, float]]:
    """p50 / p99 (ms) of batch-2 predicts per bundle, measured in interleaved rounds."""
    import time

    from tactile_force.edge.model.onnx_model import OnnxForceModel

    models = {k: OnnxForceModel(p, threads=1) for k, p in paths.items()}
    rgb = np.zeros((2, 320, 240, 3), np.uint8)
    times: dict[str, list[float]] = {k: [] for k in models}
    for _ in range(rounds):
        for k, m in models.items():
            for _ in range(calls):
                t0 = time.perf_counter_ns()
                m.predict(rgb)
                times[k].append((time.perf_counter_ns() - t0) / 1e6)
    return {k: (float(np.percentile(v, 50)), float(np.percentile(v, 99))) for k, v in times.items()}


def _unlabelled(n: int, seed: int) -> Path:
    from tactile_force.edge.synthetic import DatasetOptions, ForceDistribution, generate_dataset, paper_split

    from .reference import ABOVE_RANGE_SHARE, SPLIT

    root = ROOT / f"unlabelled-n{n}-seed{seed}"
    if not (root / "DONE").is_file():
        generate_dataset(root, DatasetOptions(n=n, seed=seed, progress=False, indenters=paper_split(SPLIT).train,
                                              forces=ForceDistribution(above_fraction=ABOVE_RANGE_SHARE)))
        (root / "DONE").write_text("ok")
    return root / "images"  # a plain image folder: the labels next to it are never read


def run(args) -> dict:
    from tactile_force.export import ModelSpec
    from tactile_force.export.compress import CompressOptions, compress_model

    from .reference import ensure_dataset, load_arrays

    data = load_arrays(ensure_dataset())
    t_rung = _rung(args.teacher)[0]
    teacher_name = f"teacher-{t_rung.name}-e{args.teacher_epochs}"
    teacher = _train_labelled(teacher_name, ModelSpec("rgbmod", t_rung.width, 1 / t_rung.k), data, args.teacher_epochs)
    t_err, t_p99 = _evaluate(_bundles(teacher, data, int8=False), data)
    print(f"teacher {teacher_name}: test {t_err}", flush=True)
    ladder = _rung(args.ladder)
    unl = _unlabelled(args.unlabelled, args.unlabelled_seed)
    res = compress_model(CompressOptions(teacher=teacher, frames=[unl], out=ROOT / f"compress-{teacher_name}",
                                         ladder=ladder, epochs=args.student_epochs, budget_ms=args.budget_ms, seed=0,
                                         latency_runs=300, show_progress=False))
    rows = []
    for rec in res.students:
        d_err, d_p99 = _evaluate(Path(rec["bundle"]), data)
        lab_ckpt = _train_labelled(f"labelled-{rec['name']}-e{args.student_epochs}",
                                   ModelSpec("rgbmod", rec["width"], 1 / rec["k"]), data, args.student_epochs)
        l_err, l_p99 = _evaluate(_bundles(lab_ckpt, data, int8=True), data)
        rows.append({"student": rec["name"], "distilled": d_err, "distilled_p99": d_p99, "labelled": l_err,
                     "labelled_p99": l_p99, "vs_teacher_heldout_unlabelled": rec["vs_teacher"]})
        print(rows[-1], flush=True)
    # Re-time every int8 student side by side (rounds of 100 batch-2 calls each, interleaved),
    # so that load from other processes on this shared host hits all of them alike.
    paths = {r["student"] + " distilled": Path(rec["bundle"]) for r, rec in zip(rows, res.students)}
    paths.update({r["student"] + " labelled": ROOT / f"labelled-{r['student']}-e{args.student_epochs}" / "int8"
                  for r in rows})
    timing = _interleaved_latency(paths)
    for r in rows:
        r["distilled_p50"], r["distilled_p99"] = timing[r["student"] + " distilled"]
        r["labelled_p50"], r["labelled_p99"] = timing[r["student"] + " labelled"]
    out = {"teacher": {"name": teacher_name, "test": t_err, "p99_fp32": t_p99}, "students": rows,
           "unlabelled": str(unl), "args": {**vars(args), "out": str(args.out)}}
    (ROOT / f"study-{args.out.stem}.json").write_text(json.dumps(out, indent=1, default=float))
    return out


def write(out: dict, argv: list[str]) -> None:
    from .machine import describe_machine, header
    from .stats import markdown_table

    t = out["teacher"]
    tre = t["test"]["re_mean"]
    table = [[f"teacher {t['name']} (labels)", "fp32", t["test"]["re_mean"], t["test"]["mae_mean"], "-",
              t["p99_fp32"], "", ""]]
    best = None
    for r in out["students"]:
        d, lab = r["distilled"], r["labelled"]
        table.append([f"{r['student']} distilled (no labels)", "int8", d["re_mean"], d["mae_mean"],
                      r["distilled_p50"], r["distilled_p99"], d["re_mean"] - tre, d["re_mean"] - lab["re_mean"]])
        table.append([f"{r['student']} trained with labels", "int8", lab["re_mean"], lab["mae_mean"],
                      r["labelled_p50"], r["labelled_p99"], lab["re_mean"] - tre, ""])
        if r["distilled_p99"] <= 1.0 and (best is None or d["re_mean"] < best["distilled"]["re_mean"]):
            best = r
    a = out["args"]
    note = (f"Teacher: RGBmod {a['teacher']} (width x 1/k) trained with labels for {a['teacher_epochs']} epochs by the "
            "reference recipe on the S1 train indenters of the reference dataset (synthetic, n=4000, seed 0). It is "
            "NOT the full-resolution RGBmod the issue asks for: training that takes hours per epoch on this 2-core "
            "machine shared with other jobs. Students: distilled on "
            f"{a['unlabelled']} UNLABELLED synthetic frames of seed {a['unlabelled_seed']} (train indenters only) for "
            f"{a['student_epochs']} epochs with augmentation; the same configs trained with labels for the same "
            "epochs (reference recipe, no augmentation). RE/MAE on the S1 held-out test indenters; p99 of a batch-2 "
            "predict, one thread, all int8 students timed in 20 interleaved rounds of 100 calls "
            "(the teacher: 300 calls once). This host is shared with other jobs: p99 here is a loaded-machine figure.")
    text = header("Distillation: students vs teacher vs labels", "python -m benchmarks.distill_study " + " ".join(argv),
                  describe_machine(), note)
    text += markdown_table(["model", "precision", "RE test", "MAE test (N)", "p50 ms", "p99 ms", "RE - teacher RE",
                            "RE - labelled RE"], table, 3) + "\n\n"
    if best is None:
        text += "No distilled student fits 1 ms p99 on this host.\n"
    else:
        dt = best["distilled"]["re_mean"] - tre
        dl = best["distilled"]["re_mean"] - best["labelled"]["re_mean"]
        text += (f"Best distilled student within 1 ms p99: {best['student']}: {dt:+.3f} RE vs the teacher "
                 f"({'within' if dt <= 0.03 else 'NOT within'} 0.03), {dl:+.3f} RE vs the same student trained with "
                 f"labels ({'within' if dl <= 0.02 else 'NOT within'} 0.02).\n")
    Path(out["args"]["out"]).write_text(text)
    print(text)


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog="python -m benchmarks.distill_study", description=__doc__.split("\n\n")[0])
    ap.add_argument("--teacher", default="0.5x4", help="teacher RGBmod as WIDTHxK (default 0.5x4)")
    ap.add_argument("--teacher-epochs", type=int, default=8)
    ap.add_argument("--student-epochs", type=int, default=12)
    ap.add_argument("--ladder", default="0.125x8,0.25x4")
    ap.add_argument("--unlabelled", type=int, default=2000)
    ap.add_argument("--unlabelled-seed", type=int, default=1)
    ap.add_argument("--budget-ms", type=float, default=1.0)
    ap.add_argument("--out", type=Path, default=OUT, help=f"Markdown page to write (default {OUT.relative_to(REPO)})")
    args = ap.parse_args(argv)
    write(run(args), argv)
    return 0


if __name__ == "__main__":
    sys.exit(main())
