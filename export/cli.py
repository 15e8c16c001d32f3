"""``tactile-force export | quantize | bundle``: argparse front ends of the export verbs.

Heavy imports (torch, onnx) happen inside the main functions, so ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

VARIANT_HELP = ("rgbmod (RGB, multi-level head), d (depth, plain ResNet-18), dmod (depth, multi-level head), "
                "rgbmod+d (RGB and depth branches)")


def _fraction(text: str) -> float:
    """'1/4' or '0.25' -> 0.25."""
    try:
        if "/" in text:
            num, den = text.split("/", 1)
            return float(num) / float(den)
        return float(text)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or a fraction like 1/4") from None


# ---------------------------------------------------------------- export

def configure_export(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = (
        "Export a trained checkpoint to a verified fp32 ONNX bundle (model.onnx + model.json).\n\n"
        "The graph takes raw uint8 BGR frames, batch first (N x 320 x 240 x 3; depth images N x 320 x 240 x 1)\n"
        "and returns the force in newtons: colour swap, layout, /255 and any downscale run inside it.\n"
        "ONNX Runtime is checked against torch on the --parity-data frames (max |diff| <= 1e-4 N) before\n"
        "anything is written; a failed check leaves no bundle.")
    p.epilog = (
        "examples:\n"
        "  tactile-force export checkpoint_epoch_24.pth.tar --variant rgbmod --out bundles/rgbmod_fp32 \\\n"
        "      --parity-data my_dataset/\n"
        "  tactile-force export ours.pth --out bundles/compact   # variant/width/scale read from the file\n"
        "  then: tactile-force quantize bundles/rgbmod_fp32 --out bundles/rgbmod_int8 --calib my_dataset/")
    p.add_argument("checkpoint", type=Path, help="trained weights (.pth / .pth.tar): the authors' format or ours")
    p.add_argument("--out", required=True, type=Path, help="bundle folder to create")
    p.add_argument("--variant", help=f"model variant: {VARIANT_HELP}. Required for the authors' checkpoints")
    p.add_argument("--width", type=float, help="channel width multiplier of a compact model (default 1.0 or the file's)")
    p.add_argument("--input-scale", type=_fraction,
                   help="network input scale 1/k, e.g. 1/4 -> 80 x 60 (default 1 or the file's)")
    p.add_argument("--parity-data", type=Path,
                   help="frames for the torch-vs-ONNX check: a dataset in the authors' layout (images/N.png, "
                        "filt_img_depth/, forces/) or a folder of PNGs. Default: random frames (noted in the manifest)")
    p.add_argument("--tolerance", type=float, default=1e-4, help="parity tolerance in N (default 1e-4)")
    p.add_argument("--opset", type=int, default=18, help="ONNX opset, >= 17 (default 18)")
    p.add_argument("--trained-on", default="", help="free text recorded as the weights' provenance")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--no-fold-preprocess", action="store_true",
                   help="keep the BGR flip and /255 as graph nodes instead of folding them into conv1's weights "
                        "(the fold is exact and ~0.1 ms faster on a compact model; parity is checked either way)")


def main_export(args: argparse.Namespace) -> int:
    from .onnx_export import ExportOptions, export_bundle

    opts = ExportOptions(variant=args.variant, width=args.width, input_scale=args.input_scale,
                         parity_data=args.parity_data, parity_tol_n=args.tolerance, opset=args.opset,
                         overwrite=args.force, trained_on=args.trained_on,
                         fold_preprocess=not args.no_fold_preprocess)
    b = export_bundle(args.checkpoint, args.out, opts)
    m = b.manifest
    print(f"wrote {b.path}  ({m.variant}, fp32, width {m.architecture['width']}, input scale "
          f"{m.architecture['input_scale']:g}, {m.architecture['gmacs']} GMACs)")
    print(f"parity vs torch: max |diff| {m.parity['max_abs_diff_n']:.2e} N on {m.parity['frames']} frames "
          f"({m.parity['data']})")
    print(f"export took {m.provenance['export_seconds']} s")
    return 0


# ---------------------------------------------------------------- quantize

def configure_quantize(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = (
        "Quantize an fp32 bundle (from 'tactile-force export') into a new bundle.\n\n"
        "  int8-static   uint8 activations, int8 per-channel weights, QDQ (fastest on CPUs); needs --calib\n"
        "  int8-dynamic  weights only, activation ranges computed per frame (for comparison)\n"
        "  fp16          half-precision weights and activations (for GPUs)\n\n"
        "The input stays uint8 frames and the force output stays float32 (the final linear layer is never\n"
        "quantized). The quantized model's difference from fp32, and its RE / MAE against ground truth when\n"
        "--calib/--eval is a labelled dataset, are written into the manifest and printed.")
    p.epilog = (
        "examples:\n"
        "  tactile-force quantize bundles/rgbmod_fp32 --out bundles/rgbmod_int8 --calib my_dataset/\n"
        "  tactile-force quantize bundles/rgbmod_fp32 --out bundles/rgbmod_int8_pct --calib frames/ \\\n"
        "      --method percentile --keep-float node_Conv_300\n"
        "  tactile-force bundle show bundles/rgbmod_fp32 --nodes     # node names for --keep-float")
    p.add_argument("bundle", type=Path, help="fp32 bundle folder (or NAME.onnx with NAME.json)")
    p.add_argument("--out", required=True, type=Path, help="bundle folder to create")
    p.add_argument("--mode", default="int8-static", choices=("int8-static", "int8-dynamic", "fp16"),
                   help="precision to produce (default int8-static)")
    p.add_argument("--calib", type=Path,
                   help="calibration frames: a dataset in the authors' layout or a folder of 320x240 PNGs "
                        "(depth PNGs for d/dmod). Required for int8-static")
    p.add_argument("--eval", type=Path, help="labelled frames for the error report (default: the --calib frames)")
    p.add_argument("--method", default="minmax", choices=("minmax", "entropy", "percentile"),
                   help="activation range calibration (default minmax)")
    p.add_argument("--percentile", type=float, default=99.999, help="percentile for --method percentile")
    p.add_argument("--bins", type=int, default=2048,
                   help="histogram bins for entropy/percentile (default 2048; entropy gets slow with more)")
    p.add_argument("--per-tensor", action="store_true", help="one weight scale per tensor instead of per channel")
    p.add_argument("--keep-float", nargs="+", default=[], metavar="NODE",
                   help="node names to leave in float (see 'tactile-force bundle show --nodes')")
    p.add_argument("--min-frames", type=int, default=10, help="refuse calibration with fewer frames (default 10)")
    p.add_argument("--max-frames", type=int, default=500, help="use at most this many calibration frames")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")


def main_quantize(args: argparse.Namespace) -> int:
    from .quantize import QuantizeOptions, quantize_bundle

    opts = QuantizeOptions(mode=args.mode, method=args.method, per_channel=not args.per_tensor,
                           keep_float=list(args.keep_float), percentile=args.percentile, histogram_bins=args.bins,
                           min_calibration_frames=args.min_frames, max_calibration_frames=args.max_frames,
                           overwrite=args.force, show_progress=True)
    b = quantize_bundle(args.bundle, args.out, opts, calibration=args.calib, eval_data=args.eval)
    m = b.manifest
    print(f"wrote {b.path}  ({m.variant}, {m.precision}, kept float: {', '.join(m.quantization['kept_float'])})")
    err = m.error
    if err:
        v = err["vs_fp32"]
        print(f"vs fp32 on {err['frames']} frames: max |diff| {v['max_abs_diff_n']:.4f} N, "
              f"mean {v['mean_abs_diff_n']:.4f} N")
        gt = err.get("vs_ground_truth")
        if gt:
            for k in ("fp32", "quantized"):
                s = gt[k]
                print(f"vs ground truth ({k}): RE {s['re_mean']:.3f} +- {s['re_std']:.3f}, "
                      f"MAE {s['mae_mean']:.3f} +- {s['mae_std']:.3f} N")
    return 0


# ---------------------------------------------------------------- bundle

def configure_bundle(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = ("Inspect a model bundle.\n\n"
                     "  show PATH     print the manifest summary (--json for all of it, --nodes for node names)\n"
                     "  verify PATH   check the sha256 and run the model once in ONNX Runtime; exit 1 if anything is off")
    p.add_argument("action", choices=("show", "verify"))
    p.add_argument("path", type=Path, help="bundle folder, or NAME.onnx with its NAME.json")
    p.add_argument("--json", action="store_true", help="show: print the full manifest as JSON")
    p.add_argument("--nodes", action="store_true", help="show: list the graph's node names and op types")


def main_bundle(args: argparse.Namespace) -> int:
    from tactile_force.edge.bundle import load_bundle

    if args.action == "verify":
        return _verify(args.path)
    b = load_bundle(args.path)
    m = b.manifest
    if args.json:
        print(m.to_json(), end="")
        return 0
    print(f"bundle    {b.path}  (sha256 {m.sha256[:16]}... verified)")
    print(f"variant   {m.variant}   precision {m.precision}")
    for s in m.inputs:
        print(f"input     {s.name}: {s.shape} {s.dtype} {s.layout} {s.colour_order}")
    print(f"output    {m.output.name}: {m.output.shape} {m.output.dtype} [{m.output.unit}]")
    print(f"graph     {'; '.join(m.preprocessing_in_graph)}")
    a = m.architecture
    if a:
        print(f"network   width {a.get('width')}, input scale {a.get('input_scale')}, input {a.get('network_input_hw')}, "
              f"{a.get('gmacs')} GMACs, head folded: {a.get('head_folded')}")
    if m.parity:
        print(f"parity    max |ORT - torch| {m.parity['max_abs_diff_n']:.2e} N on {m.parity['frames']} frames")
    if m.quantization:
        q = m.quantization
        print(f"quant     {q.get('format')}, method {q.get('method', '-')}, per-channel {q.get('per_channel')}, "
              f"kept float {q.get('kept_float')}")
    if m.error:
        v = m.error["vs_fp32"]
        print(f"error     vs fp32 max {v['max_abs_diff_n']:.4f} N, mean {v['mean_abs_diff_n']:.4f} N "
              f"({m.error['frames']} frames)")
    print(f"weights   {json.dumps(m.provenance)}")
    if args.nodes:
        import onnx

        for n in onnx.load(str(b.onnx_path)).graph.node:
            print(f"  {n.op_type:<18} {n.name}")
    return 0


def _verify(path: Path) -> int:
    import numpy as np
    import onnxruntime as ort

    from tactile_force.edge.bundle import load_bundle
    from tactile_force.edge.errors import BundleError

    b = load_bundle(path)
    try:
        sess = ort.InferenceSession(str(b.onnx_path), providers=["CPUExecutionProvider"])
    except Exception as exc:  # ORT raises its own exception types for corrupted graphs
        raise BundleError(f"{b.onnx_path}: ONNX Runtime cannot load it ({str(exc).splitlines()[0][:200]})") from None
    names = {i.name for i in sess.get_inputs()}
    want = {s.name for s in b.manifest.inputs}
    if names != want:
        raise BundleError(f"{b.onnx_path}: graph inputs {sorted(names)} do not match the manifest's {sorted(want)}")
    feed = {s.name: np.zeros([2] + list(s.shape[1:]), dtype=np.uint8) for s in b.manifest.inputs}
    out = sess.run([b.manifest.output.name], feed)[0]
    if out.dtype != np.float32 or out.reshape(-1).shape != (2,) or not np.all(np.isfinite(out)):
        raise BundleError(f"{b.onnx_path}: output {out.shape} {out.dtype} is not 2 finite float32 forces for 2 frames")
    print(f"ok: {b.path} ({b.manifest.variant}, {b.manifest.precision}) sha256 matches, runs, output float32 N",
          file=sys.stdout)
    return 0
