"""The quantization page (quantization.md): ``tactile-force study`` (:func:`tactile_force.export.study.run_study`,
the installed verb's code) on the reference compact RGBmod (rgbmod-w0.25-s4: the trained one
when the reference recipe made it, else random weights), calibrated on the synthetic train
split and evaluated on the synthetic test split, through the runtime; then evaluating a
trained model at a smaller input scale than it was trained for (the network is fully
convolutional + global pooling, so a checkpoint exports at any scale 1/k).

    python -m benchmarks quant --out docs/benchmarks
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .bundles import DEFAULT_CONFIG, latency_bundle, trained_models, trained_models_dir
from .harness.data import predict_all
from .harness.latency import LatencyCase, ModelConfig, measure, parse_config
from .harness.machine import command_line
from .harness.paths import cache_dir, source_commit
from .harness.stats import markdown_table
from .reference import synthetic_test


def study_dir() -> Path:
    """Where the study's bundles are kept (by source model)."""
    return cache_dir() / "quant_study"


def _errors(model, test, fp32_pred: np.ndarray | None) -> dict:
    from tactile_force.edge.data.metrics import error_stats

    pred = predict_all(model, test)
    st = error_stats(pred, test.force)
    out = {"re": st.re_mean, "re_std": st.re_std, "mae": st.mae_mean, "pred": pred,
           "nonfinite": int((~np.isfinite(pred)).sum())}
    out["max_vs_fp32"] = float(np.abs(pred - fp32_pred).max()) if fp32_pred is not None else 0.0
    return out


def split_folder(part: str, limit: int | None = None) -> Path:
    """The reference dataset's ``part`` split (S1: 'train' / 'val' / 'test') as an authors'-layout
    folder of links (cached), what ``tactile-force study`` reads; at most ``limit`` samples."""
    from tactile_force.edge import AuthorsDataset
    from tactile_force.edge.synthetic import paper_split, split_ids

    from . import reference

    root = reference.ensure_dataset()
    ids = sorted(split_ids(AuthorsDataset(root).meta, paper_split(reference.SPLIT))[part], key=int)
    ids = ids[:limit] if limit is not None else ids
    out = cache_dir() / f"{root.name}-{reference.SPLIT}-{part}-{len(ids)}"
    if (out / "DONE").is_file():
        return out
    for sub in ("images", "forces"):
        (out / sub).mkdir(parents=True, exist_ok=True)
    for n in ids:
        for src, dst in ((root / "images" / f"{n}.png", out / "images" / f"{n}.png"),
                         (root / "forces" / f"force_{n}.txt", out / "forces" / f"force_{n}.txt")):
            if not dst.exists():
                os.symlink(src, dst)
    (out / "DONE").write_text("")
    return out


def virtual_background() -> Path:
    """A no-contact frame of the virtual DIGIT (the synthetic data's sensor), as PNG."""
    import cv2
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    path = cache_dir() / "virtual_digit_background.png"
    if not path.is_file():
        path.parent.mkdir(parents=True, exist_ok=True)
        frame = VirtualDigit(VirtualDigitOptions()).render(None, 0.0, led_gain=(1.0, 1.0, 1.0)).frame
        cv2.imwrite(str(path), frame)
    return path


def run(args, argv) -> None:
    from tactile_force.export.study import StudyOptions, markdown, run_study

    cfg = parse_config(DEFAULT_CONFIG)
    trained_dir = trained_models_dir() / DEFAULT_CONFIG / "fp32"
    trained = (trained_dir / "model.json").is_file()
    fp32 = trained_dir if trained else latency_bundle(cfg, "fp32")
    test_dir = split_folder("test", 60 if args.quick else None)
    calib_dir = split_folder("train", 200)
    # Study bundles are keyed by the fp32 source's hash: retraining never reuses stale ones.
    src = json.loads((Path(fp32) / "model.json").read_text())["sha256"][:10]
    out = study_dir() / f"{cfg.name}-{src}"
    report = run_study(fp32, test_dir, out, StudyOptions(quick=args.quick, frames=100 if args.quick else 1000,
                                                         show_progress=True),
                       calibration=calib_dir, background=virtual_background(), command=command_line(argv),
                       log=lambda s: print(f"quant: {s}", flush=True))
    weights = (f"TRAINED {DEFAULT_CONFIG} (reference recipe)" if trained else
               f"RANDOM-weight {DEFAULT_CONFIG} ({DEFAULT_CONFIG} not trained yet): RE against ground truth is "
               "meaningless here, only the error against fp32 is informative")
    test = synthetic_test(False)
    if args.quick:
        test.rgb, test.force = test.rgb[:40], test.force[:40]
    scale_rows, scale_note = input_scale_study(test, args.quick)
    # the study's report.md with the commit that measured, after its command line
    head, sep, rest = markdown(report, "Quantization study").partition(f"Command: `{report.command}`\n")
    text = (head + sep + f"\nCommit: {source_commit()}\n" + rest).rstrip() + "\n\n" + "\n".join([
        f"Model: {weights}. The study's bundles: `{out}`. The same study runs on your model, data and host "
        "with `tactile-force study` ([docs/bench.md](../bench.md)).", "",
        "## Evaluating at a smaller input scale than trained", "", scale_note, "",
        markdown_table(["checkpoint", "trained at", "evaluated at", "RE", "MAE (N)", "inference p50 ms"], scale_rows, 4)
        if scale_rows else "", ""])
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "quantization.md").write_text(text)
    print(f"wrote {args.out / 'quantization.md'}")


def input_scale_study(test, quick: bool) -> tuple[list[list[object]], str]:
    """Export each trained RGBmod checkpoint at half its training scale (fp32) and evaluate."""
    from tactile_force.edge import OnnxForceModel
    from tactile_force.export import ExportOptions, export_bundle

    rows = []
    for tm in trained_models():
        c = tm.config
        if c.variant != "rgbmod" or "fp32" not in tm.bundles or 240 % (2 * c.k) or 320 % (2 * c.k):
            continue
        native = _errors(OnnxForceModel(tm.bundles["fp32"]), test, None)
        lat = measure(LatencyCase(c, "fp32", frames=100, bundle=tm.bundles["fp32"])).stages["inference"].p50
        rows.append([c.name, f"1/{c.k}", f"1/{c.k} (native)", native["re"], native["mae"], lat])
        src = json.loads((tm.bundles["fp32"] / "model.json").read_text())["sha256"][:10]
        dest = study_dir() / f"{c.name}-{src}-at-s{2 * c.k}"
        if not (dest / "model.json").is_file():
            export_bundle(tm.root / "model.pth", dest, ExportOptions(input_scale=1.0 / (2 * c.k), overwrite=True,
                                                                      name=dest.name, parity_tol_n=1e-3))
        e = _errors(OnnxForceModel(dest), test, None)
        lat = measure(LatencyCase(ModelConfig(c.variant, c.width, 2 * c.k), "fp32", frames=100, bundle=dest))
        rows.append([c.name, f"1/{c.k}", f"1/{2 * c.k}", e["re"], e["mae"], lat.stages["inference"].p50])
    if rows:
        note = ("Each trained RGBmod checkpoint, exported again at half its training input scale (same weights, "
                "fp32), on the same test frames.")
    else:
        note = ("No trained RGBmod checkpoint yet, so this part is empty; full-resolution (1/1) models are not "
                "trained by the reference recipe (hours per epoch on this CPU), so the paper's 'full-res model at a "
                "smaller scale' case cannot be measured here.")
    return rows, note
