"""Quantization study on the default config (rgbmod-w0.25-s4): calibration method x
per-channel / per-tensor x which nodes stay float, and evaluating a trained model at a
smaller input scale than it was trained for (the network is fully convolutional + global
pooling, so a checkpoint exports at any scale 1/k)."""

from __future__ import annotations

import json

import shutil
from pathlib import Path

import numpy as np

from .bundles import CACHE, DEFAULT_CONFIG, TRAINED_MODELS, ModelConfig, latency_bundle, parse_config, trained_models
from .evaluate import predict_all, synthetic_test
from .latency import LatencyCase, measure
from .machine import command_line, describe_machine, header
from .stats import markdown_table

STUDY = CACHE / "quant_study"


def first_conv(bundle_path: Path) -> str:
    import onnx

    m = onnx.load(str(bundle_path / "model.onnx"))
    return next(n.name for n in m.graph.node if n.op_type == "Conv")


def _calibration(cfg: ModelConfig, trained: bool, n: int):
    from .frames import frame_pool

    if not trained:
        return frame_pool().calibration(cfg.variant, min(n, 64))
    from . import reference

    data = reference.load_arrays(reference.ensure_dataset())
    return reference.calibration_data(reference.CONFIGS[cfg.name], data, "train", n)


def _errors(model, test, fp32_pred: np.ndarray | None) -> dict:
    from tactile_force.edge.metrics import error_stats

    pred = predict_all(model, test)
    st = error_stats(pred, test.force)
    out = {"re": st.re_mean, "re_std": st.re_std, "mae": st.mae_mean, "pred": pred, "nonfinite": int((~np.isfinite(pred)).sum())}
    out["max_vs_fp32"] = float(np.abs(pred - fp32_pred).max()) if fp32_pred is not None else 0.0
    return out


def run(args, argv) -> None:
    from tactile_force.edge import OnnxForceModel
    from tactile_force.export import QuantizeOptions, quantize_bundle

    cfg = parse_config(DEFAULT_CONFIG)
    trained_dir = TRAINED_MODELS / DEFAULT_CONFIG / "fp32"
    trained = (trained_dir / "model.json").is_file()
    fp32 = trained_dir if trained else latency_bundle(cfg, "fp32")
    test = synthetic_test(False)
    if args.quick:
        test.rgb, test.force = test.rgb[:40], test.force[:40]
    calib = _calibration(cfg, trained, 64 if args.quick else 200)
    ref = _errors(OnnxForceModel(fp32), test, None)
    # Cached study bundles are keyed by the fp32 source's hash: retraining never reuses stale ones.
    src = json.loads((Path(fp32) / "model.json").read_text())["sha256"][:10]
    conv1 = first_conv(fp32)
    rows = [["fp32 (reference)", "-", "-", "-", ref["re"], ref["mae"], 0.0, ref["nonfinite"],
             measure(LatencyCase(cfg, "fp32", frames=100 if args.quick else 300, bundle=fp32)).stages["inference"].p50]]
    methods = ("minmax", "percentile") if args.quick else ("minmax", "entropy", "percentile")
    keeps = {"final linear only": [], f"+ first conv ({conv1})": [conv1]}
    for method in methods:
        for per_channel in (True, False):
            for keep_name, keep in keeps.items():
                dest = STUDY / f"{cfg.name}-{src}-{method}-{'pc' if per_channel else 'pt'}-{len(keep)}"
                if not (dest / "model.json").is_file():
                    shutil.rmtree(dest, ignore_errors=True)
                    quantize_bundle(fp32, dest, QuantizeOptions(method=method, per_channel=per_channel, keep_float=keep,
                                                                overwrite=True, name=dest.name),
                                    calibration=calib, eval_data=calib.subset(16))
                e = _errors(OnnxForceModel(dest), test, ref["pred"])
                lat = measure(LatencyCase(cfg, "int8-static", frames=100 if args.quick else 300, bundle=dest))
                rows.append(["int8 static", method, "per channel" if per_channel else "per tensor", keep_name, e["re"],
                             e["mae"], e["max_vs_fp32"], e["nonfinite"], lat.stages["inference"].p50])
                print(f"quant {method} pc={per_channel} keep={keep_name}: RE {e['re']:.4f} max|int8-fp32| "
                      f"{e['max_vs_fp32']:.4f} N", flush=True)
    for mode in ("int8-dynamic", "fp16"):
        dest = STUDY / f"{cfg.name}-{src}-{mode}"
        if not (dest / "model.json").is_file():
            shutil.rmtree(dest, ignore_errors=True)
            quantize_bundle(fp32, dest, QuantizeOptions(mode=mode, overwrite=True, name=dest.name),
                            calibration=calib, eval_data=calib.subset(16))
        e = _errors(OnnxForceModel(dest), test, ref["pred"])
        lat = measure(LatencyCase(cfg, mode, frames=100 if args.quick else 300, bundle=dest))
        rows.append([mode, "-", "per channel", "final linear only", e["re"], e["mae"], e["max_vs_fp32"], e["nonfinite"],
                     lat.stages["inference"].p50])
    scale_rows, scale_note = input_scale_study(test, args.quick)
    m = describe_machine()
    weights = (f"TRAINED {DEFAULT_CONFIG} (reference recipe)" if trained else
               f"RANDOM-weight {DEFAULT_CONFIG} ({DEFAULT_CONFIG} not trained yet): RE against ground truth is "
               "meaningless here, only the int8-vs-fp32 divergence is informative")
    text = header("Quantization study", command_line(argv), m,
                  f"Model: {weights}. Calibration: {len(calib)} frames ({calib.source}). Evaluated on {test.source}"
                  f"{' (first 40: --quick)' if args.quick else ''}. Inference p50: one thread, frames in contact.") + "\n".join([
        "## Calibration method x granularity x nodes kept float", "",
        markdown_table(["mode", "calibration", "weights", "kept float", "RE", "MAE (N)", "max abs vs fp32 (N)",
                        "non-finite", "inference p50 ms"], rows, 4), "",
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
        dest = STUDY / f"{c.name}-{src}-at-s{2 * c.k}"
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
