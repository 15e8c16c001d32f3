"""``tactile-force export | quantize | bundle``: argparse front ends of the export verbs.

Heavy imports (torch, onnx) happen inside the main functions, so ``--help`` is instant.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tactile_force.edge.cli.args import float_in, int_at_least, within
from tactile_force.edge.limits import READINGS
from tactile_force.edge.typed_json import Check

VARIANT_HELP = ("rgbmod (RGB, multi-level head), d (depth, plain ResNet-18), dmod (depth, multi-level head), "
                "rgbmod+d (RGB and depth branches)")


_INPUT_SCALE = Check(gt=0, le=1)


def _fraction(text: str) -> float:
    """'1/4' or '0.25' -> 0.25, a scale in (0, 1]."""
    try:
        if "/" in text:
            num, den = text.split("/", 1)
            v = float(num) / float(den)
        else:
            v = float(text)
    except (ValueError, ZeroDivisionError):
        raise argparse.ArgumentTypeError(f"{text!r} is not a number or a fraction like 1/4") from None
    return float(within(float, _INPUT_SCALE)(repr(v)))


_fraction.check = _INPUT_SCALE  # type: ignore[attr-defined]


def _opset(text: str) -> int:
    """argparse type: an ONNX opset from 17 to the newest one the installed onnx package knows."""
    value = int(int_at_least(17, 1000)(text))
    import onnx

    newest = onnx.defs.onnx_opset_version()
    if value > newest:
        raise argparse.ArgumentTypeError(f"{value}: the installed onnx {onnx.__version__} knows opsets up to {newest}; "
                                         "expected 17..{newest} (default 18)".replace("{newest}", str(newest)))
    return value


# the range tests read; the newest opset the installed onnx knows bounds it further
_opset.check = Check(ge=17, le=1000)  # type: ignore[attr-defined]


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
    p.add_argument("--width", type=float_in(0.0, 16.0, low_open=True),
                   help="channel width multiplier of a compact model (default 1.0 or the file's)")
    p.add_argument("--input-scale", type=_fraction,
                   help="network input scale 1/k, e.g. 1/4 -> 80 x 60 (default 1 or the file's)")
    p.add_argument("--parity-data", type=Path,
                   help="frames for the torch-vs-ONNX check: a dataset in the authors' layout (images/N.png, "
                        "filt_img_depth/, forces/) or a folder of PNGs. Default: random frames (noted in the manifest)")
    p.add_argument("--tolerance", type=float_in(0.0, 1000.0, low_open=True), default=1e-4,
                   help="parity tolerance in N (default 1e-4)")
    p.add_argument("--opset", type=_opset, default=18,
                   help="ONNX opset, 17 up to the newest the installed onnx knows (default 18); the manifest records "
                        "the opset the graph really declares")
    p.add_argument("--trained-on", default="", help="free text recorded as the weights' provenance")
    p.add_argument("--background", type=Path,
                   help="no-contact frame of the --parity-data sensor: the manifest's data statistics (from the "
                        "parity frames) then also record contact sizes for the runtime's contact-size check")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")
    p.add_argument("--no-fold-preprocess", action="store_true",
                   help="keep the BGR flip and /255 as graph nodes instead of folding them into conv1's weights "
                        "(the fold is exact and ~0.1 ms faster on a compact model; parity is checked either way)")


def _warn_data_stats(tool: str, b) -> None:
    """Say loudly on stderr when the written bundle's honesty checks are (partly) off."""
    m = b.manifest
    if m.data_stats is None:
        print(f"tactile-force {tool}: WARNING: {m.data_stats_missing or 'no data statistics recorded'}",
              file=sys.stderr)
    elif not m.data_stats.contact_measured:
        print(f"tactile-force {tool}: warning: no --background given: the data statistics hold the frames' colours "
              "(out-of-distribution check on) but not their contact sizes (contact-size check off)", file=sys.stderr)


def main_export(args: argparse.Namespace) -> int:
    from .onnx_export import ExportOptions, export_bundle

    opts = ExportOptions(variant=args.variant, width=args.width, input_scale=args.input_scale,
                         parity_data=args.parity_data, parity_tol_n=args.tolerance, opset=args.opset,
                         overwrite=args.force, trained_on=args.trained_on,
                         fold_preprocess=not args.no_fold_preprocess, background=args.background)
    b = export_bundle(args.checkpoint, args.out, opts)
    _warn_data_stats("export", b)
    from tactile_force.edge.cli.bundle import describe_manifest

    print(f"wrote {b.path}  (export took {b.manifest.provenance.export_seconds} s)")
    for line in describe_manifest(b)[1:]:
        print(line)
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
    p.add_argument("--percentile", type=float_in(0.0, 100.0, low_open=True), default=99.999,
                   help="percentile for --method percentile (0 < p <= 100)")
    p.add_argument("--bins", type=within(int, Check(ge=2, le=1_000_000)), default=2048,
                   help="histogram bins for entropy/percentile (default 2048; entropy gets slow with more)")
    p.add_argument("--per-tensor", action="store_true", help="one weight scale per tensor instead of per channel")
    p.add_argument("--weight-bits", type=int, choices=(7, 8), default=7,
                   help="int8-static weights in 7 bits (default: exact with the fused int8 kernels on every CPU) or 8 "
                        "(x86-64 CPUs without VNNI then run the graph unfused, slower: docs/runtime.md)")
    p.add_argument("--keep-float", nargs="+", default=[], metavar="NODE",
                   help="node names to leave in float (see 'tactile-force bundle show --nodes')")
    p.add_argument("--min-frames", type=within(int, READINGS), default=10,
                   help="refuse calibration with fewer frames (>= 1, default 10)")
    p.add_argument("--max-frames", type=within(int, READINGS), default=500,
                   help="use at most this many calibration frames (>= 1, default 500; there is no 'unlimited')")
    p.add_argument("--background", type=Path,
                   help="no-contact frame of the calibration frames' sensor: records their statistics in the "
                        "manifest so the runtime flags out_of_distribution frames")
    p.add_argument("--force", action="store_true", help="replace --out if it exists")


def main_quantize(args: argparse.Namespace) -> int:
    from .quantize import QuantizeOptions, quantize_bundle

    if args.min_frames > args.max_frames:
        print(f"tactile-force quantize: error: --min-frames {args.min_frames} is above --max-frames "
              f"{args.max_frames}; expected min <= max", file=sys.stderr)
        return 2
    opts = QuantizeOptions(mode=args.mode, method=args.method, per_channel=not args.per_tensor,
                           keep_float=list(args.keep_float), percentile=args.percentile, histogram_bins=args.bins,
                           min_calibration_frames=args.min_frames, max_calibration_frames=args.max_frames,
                           overwrite=args.force, show_progress=True, background=args.background,
                           weight_bits=args.weight_bits)
    b = quantize_bundle(args.bundle, args.out, opts, calibration=args.calib, eval_data=args.eval)
    _warn_data_stats("quantize", b)
    from tactile_force.edge.cli.bundle import describe_manifest

    print(f"wrote {b.path}")
    for line in describe_manifest(b)[1:]:
        print(line)
    return 0
