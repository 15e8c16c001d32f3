"""Error against run time (error_vs_runtime.md, .json, .png) of every trained reference bundle:
RE / MAE (mean +- std, per 1 N bin) on the held-out-indenter synthetic test split and on the
real AUROVA frames, beside p50 / p99 latency; a Markdown table and a Pareto plot.

    python -m benchmarks error [--out DIR]
"""

from __future__ import annotations

import json
from pathlib import Path

from .bundles import trained_models
from .harness.data import predict_all, real_frames
from .harness.latency import LatencyCase, measure
from .harness.machine import command_line, describe_machine, header
from .harness.stats import markdown_table
from .reference import CONFIGS, synthetic_test


def evaluate_trained(frames: int = 300) -> list[dict]:
    """One dict per (trained config, bundle): errors on both datasets and latency."""
    from tactile_force.edge import OnnxForceModel
    from tactile_force.edge.data.metrics import error_report

    rows = []
    real = real_frames()
    cache: dict[bool, object] = {}
    for tm in trained_models():
        needs_depth = tm.config.variant != "rgbmod"
        if needs_depth not in cache:
            cache[needs_depth] = synthetic_test(needs_depth)
        test = cache[needs_depth]
        for precision, path in tm.bundles.items():
            model = OnnxForceModel(path, threads=1)
            pred = predict_all(model, test)
            rep = error_report(pred, test.force)
            rr = None
            if real is not None and (not needs_depth or real.depth is not None):
                rr = error_report(predict_all(model, real), real.force)
            lat = measure(LatencyCase(tm.config, precision, frames=frames, warmup=20, bundle=path))
            key = "total" if needs_depth else "gate+inference"
            rows.append({"config": tm.config.name, "label": tm.config.label, "precision": precision,
                         "gmacs": lat.gmacs, "synthetic": rep, "real": rr, "p50": lat.stages[key].p50,
                         "p99": lat.stages[key].p99, "latency_stage": key, "test_source": test.source,
                         "epochs": tm.record.get("best_epoch")})
            print(f"{tm.config.name} {precision}: RE {rep.overall.re_mean:.3f} MAE {rep.overall.mae_mean:.3f} N, "
                  f"p50 {rows[-1]['p50']:.3f} ms", flush=True)
    return rows


def _cell(st) -> str:
    return "-" if st is None else f"{st.re_mean:.3f} +- {st.re_std:.3f}"


def _mae(st) -> str:
    return "-" if st is None else f"{st.mae_mean:.2f} +- {st.mae_std:.2f}"


def pareto_plot(rows: list[dict], path: Path, title: str) -> Path:
    """RE on the synthetic test split against p99, one point per bundle, the 1 ms budget
    (:func:`tactile_force.edge.report.plots.error_vs_latency`)."""
    from tactile_force.edge.report.plots import ParetoPoint, error_vs_latency

    pts = [ParetoPoint(f"{r['config']} {'int8' if r['precision'] == 'int8-static' else r['precision']}", r["p99"],
                       r["synthetic"].overall.re_mean) for r in rows]
    return error_vs_latency(pts, 1.0, path, ylabel="RE on held-out synthetic indenters", title=title)


def run(args, argv) -> None:
    out: Path = args.out
    out.mkdir(parents=True, exist_ok=True)
    rows = evaluate_trained(100 if args.quick else 300)
    trained = {r["config"] for r in rows}
    missing = [c for c in CONFIGS if c not in trained]
    table = [[r["label"], r["precision"], r["gmacs"], _cell(r["synthetic"].overall), _mae(r["synthetic"].overall),
              _cell(r["real"].overall if r["real"] else None), _mae(r["real"].overall if r["real"] else None),
              r["p50"], r["p99"]] for r in rows]
    bins = sorted({b for r in rows for b in r["synthetic"].per_bin},
                  key=lambda b: float(b.split("-")[0]) if b[0].isdigit() else 99)
    bin_rows = [[r["config"], r["precision"]] + [_cell(r["synthetic"].per_bin.get(b)) for b in bins]
                for r in rows]
    m = describe_machine()
    text = header("Error against run time", command_line(argv), m, NOTE) + "\n".join([
        "## Trained reference bundles", "",
        markdown_table(["model", "precision", "GMACs", "RE synthetic test", "MAE synthetic (N)", "RE real AUROVA (11)",
                        "MAE real (N)", "p50 ms", "p99 ms"], table) if rows else "No trained bundles yet.", "",
        f"Not trained (no benchmarks/cache/models/<config>/record.json): {', '.join(missing) or 'none'}.", "",
        "![Pareto plot](error_vs_runtime.png)", "",
        "## Per-sensor calibration and distilled students", "",
        CALIBRATION_POINTER, "",
        "## RE per 1 N force bin (synthetic test split)", "",
        markdown_table(["config", "precision"] + bins, bin_rows) if rows else "", "",
    ])
    if rows:
        pareto_plot(rows, out / "error_vs_runtime.png", f"error vs p99 latency ({m.cpu}, 1 thread)")
        int8_vs_fp32 = []
        for c in trained:
            d = {r["precision"]: r["synthetic"].overall.re_mean for r in rows if r["config"] == c}
            if "fp32" in d and "int8-static" in d:
                int8_vs_fp32.append([c, d["fp32"], d["int8-static"], d["int8-static"] - d["fp32"],
                                     "yes" if abs(d["int8-static"] - d["fp32"]) <= 0.02 else "NO"])
        text += "\n## int8 vs fp32 RE (must be within 0.02)\n\n" + markdown_table(
            ["config", "RE fp32", "RE int8", "difference", "within 0.02"], int8_vs_fp32, 4) + "\n"
        (out / "error_vs_runtime.json").write_text(json.dumps(
            [{**{k: v for k, v in r.items() if k not in ("synthetic", "real")}, "synthetic": r["synthetic"].as_dict(),
              "real": r["real"].as_dict() if r["real"] else None} for r in rows], indent=1, default=float))
    (out / "error_vs_runtime.md").write_text(text)
    print(f"wrote {out / 'error_vs_runtime.md'}")


CALIBRATION_POINTER = ("`tactile-force calibrate-force` fitted on the 11 real AUROVA frames, leave-one-out and on the "
                       "11 held-out frames of the same grasp: [calibration.md](calibration.md) "
                       "(`python -m benchmarks.calibration`). Distilled students (`tactile-force compress`) "
                       "against their teacher and against the same students trained with labels, on the held-out "
                       "synthetic indenters: [distillation.md](distillation.md) and "
                       "[distillation_small_student.md](distillation_small_student.md) (measured by code since "
                       "retired; each page names its commit).")

NOTE = """Models: the reference recipe (`python -m benchmarks.reference`), trained from scratch on
SYNTHETIC virtual DIGIT frames only (S1 split: 14 train / 2 val / 2 held-out test indenters).
RE = |f_pred - f_gt| / f_gt, MAE in N (the paper's metrics, edge/data/metrics.py). Real frames:
the 11 labelled AUROVA DIGIT frames of one grasp (another sensor unit, real gel, a round
indenter); synthetic-only models are expected to do badly there, and the figures are given
as measured. Depth variants read the paper's filtered depth images on the real frames.
Latency: p50 / p99 over 300 frames in contact, one thread, gate + inference (RGBmod) or
gate + depth + inference (depth variants)."""
