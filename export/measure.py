"""Export / quantization figures in one run: export time, parity, int8-vs-fp32 error, latency.

    python -m tactile_force.export.measure --data ../shared/data/aurova_digit_grasp [--checkpoint CKPT]

Without --checkpoint the networks get random trunks (seeded) whose head is ridge-fitted to the
data's forces so outputs are in newtons; fine for time, parity, latency and the size of the
int8 error in N, but not a statement about a trained model's accuracy. Latency: onnxruntime CPU, 1 intra-op thread,
batch 1, median of --iters runs after warm-up, frames taken from --data.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np
import torch

from .calibration import CalibrationData
from .checkpoint import model_from_checkpoint
from .onnx_export import ExportOptions, export_bundle, ort_session, run_ort
from .preprocess import Preprocess
from .quantize import QuantizeOptions, quantize_bundle
from .zoo import build_model


@torch.no_grad()
def fit_head(model: torch.nn.Module, data: CalibrationData, input_scale: float, ridge: float = 1e-2) -> None:
    """Give a random-weight RGBmod forces in newtons: ridge-fit fc4 (layer4 part) to the data's labels."""
    x = Preprocess(input_scale)(torch.from_numpy(data.inputs["rgb"]))
    p4 = model.pyramid(x)[2].double()
    mu = p4.mean(0)
    a = p4 - mu
    f = torch.from_numpy(data.forces)
    w = torch.linalg.solve(a.T @ a + ridge * torch.eye(a.shape[1], dtype=torch.float64), a.T @ (f - f.mean()))
    model.fc4.weight.zero_()
    model.fc4.weight[0, -a.shape[1]:] = w.float()
    model.fc4.bias.fill_(float(f.mean() - mu @ w))


def latency_ms(onnx_path: Path, data: CalibrationData, iters: int) -> dict:
    """Median / p90 single-thread latency in ms of one frame."""
    sess = ort_session(onnx_path.read_bytes(), threads=1)
    feeds = list(data.batches(1))
    for f in feeds[:3]:
        sess.run(None, f)
    times = []
    for i in range(iters):
        t = time.perf_counter()
        sess.run(None, feeds[i % len(feeds)])
        times.append((time.perf_counter() - t) * 1e3)
    return {"median_ms": round(float(np.median(times)), 3), "p90_ms": round(float(np.percentile(times, 90)), 3)}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m tactile_force.export.measure", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--data", type=Path, required=True, help="authors'-layout dataset (parity, calibration, latency)")
    p.add_argument("--checkpoint", type=Path, help="authors' RGBmod checkpoint (default: random weights)")
    p.add_argument("--iters", type=int, default=30)
    p.add_argument("--compact", default="0.25,0.25", help="width,input_scale of the compact model")
    args = p.parse_args(argv)
    data = CalibrationData.from_path(args.data, "rgbmod")
    w, s = (float(x) for x in args.compact.split(","))
    torch.manual_seed(0)
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for label, width, scale in (("full", 1.0, 1.0), ("compact", w, s)):
            if label == "full" and args.checkpoint:
                src = model_from_checkpoint(args.checkpoint, "rgbmod")[0]
            else:
                src = build_model("rgbmod", width).eval()
                fit_head(src, data, scale)
            t = time.perf_counter()
            fp32 = export_bundle(src, tmp / f"{label}_fp32", ExportOptions(variant="rgbmod", width=width,
                                                                           input_scale=scale, parity_data=data))
            export_s = time.perf_counter() - t
            t = time.perf_counter()
            int8 = quantize_bundle(fp32, tmp / f"{label}_int8", QuantizeOptions(), calibration=data)
            quant_s = time.perf_counter() - t
            rows[label] = {
                "width": width, "input_scale": scale, "gmacs": fp32.manifest.architecture["gmacs"],
                "export_s": round(export_s, 2), "parity_max_abs_diff_n": fp32.manifest.parity["max_abs_diff_n"],
                "quantize_s": round(quant_s, 2),
                "int8_vs_fp32_max_abs_diff_n": round(int8.manifest.error["vs_fp32"]["max_abs_diff_n"], 5),
                "int8_vs_fp32_mean_abs_diff_n": round(int8.manifest.error["vs_fp32"]["mean_abs_diff_n"], 5),
                "fp32_force_span_n": round(float(np.ptp(run_ort(ort_session(fp32.onnx_path.read_bytes()), data))), 3),
                "fp32_latency": latency_ms(fp32.onnx_path, data, args.iters),
                "int8_latency": latency_ms(int8.onnx_path, data, args.iters),
            }
    import onnxruntime

    print(json.dumps({"onnxruntime": onnxruntime.__version__, "frames": len(data),
                      "weights": str(args.checkpoint) if args.checkpoint else "random trunk (seed 0), head fitted to --data", **rows}, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
