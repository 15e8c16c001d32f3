"""int8 with and without the head's input (pooled features + concat) kept in float.

    python -m benchmarks.int8_head            # writes docs/benchmarks/int8_head.md

For each model: fp32 bundle, int8-static (minmax, per channel) with ``float_head_inputs``
off and on, calibrated on the same 64 virtual DIGIT frames; max / mean |int8 - fp32| (N) on
real frames (the 11 AUROVA frames + 42 FOTS ball presses) and p50 / p99 of a batch-2
``OnnxForceModel.predict`` (one thread).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from .frames import CACHE, REPO

OUT = REPO / "docs" / "benchmarks" / "int8_head.md"
SHARED = REPO.parent / "shared" / "data"


def _real_frames() -> np.ndarray:
    import cv2
    from tactile_force.edge import AuthorsDataset

    ds = AuthorsDataset(SHARED / "aurova_digit_grasp")
    frames = [ds.load(n).frame for n in ds.ids]
    frames += [cv2.imread(str(p)) for p in sorted((SHARED / "fots_digit" / "ball_presses").glob("*.png"))]
    return np.stack([f for f in frames if f is not None and f.shape == (320, 240, 3)])


def _synthetic(n: int = 64) -> np.ndarray:
    from tactile_force.edge import AuthorsDataset
    from tactile_force.edge.synthetic import DatasetOptions, generate_dataset

    root = CACHE / "int8_head_calib"
    if not (root / "images").is_dir():
        generate_dataset(root, DatasetOptions(n=n, seed=99, progress=False))
    ds = AuthorsDataset(root)
    return np.stack([ds.load(k).frame for k in ds.ids])


def _latency(path: Path, runs: int) -> tuple[float, float]:
    from tactile_force.edge.model.onnx_model import MAX_BATCH, OnnxForceModel

    m = OnnxForceModel(path, threads=1)
    rgb = np.zeros((MAX_BATCH, 320, 240, 3), np.uint8)
    t = []
    for _ in range(runs):
        t0 = time.perf_counter_ns()
        m.predict(rgb)
        t.append((time.perf_counter_ns() - t0) / 1e6)
    return float(np.percentile(t, 50)), float(np.percentile(t, 99))


def study(models: list[tuple[str, float, int, Path | None]], runs: int = 100) -> list[list]:
    """models: (label, width, k, trained checkpoint or None for random weights, seed 0)."""
    import torch
    from tactile_force.export import (
        CalibrationData,
        ExportOptions,
        ForceNet,
        ModelSpec,
        QuantizeOptions,
        build_model,
        export_bundle,
        quantize_bundle,
    )
    from tactile_force.export.onnx_export import ort_session, run_ort

    real = _real_frames()
    calib = CalibrationData({"rgb": _synthetic()}, None, "64 virtual DIGIT frames (seed 99)",
                            [str(i) for i in range(64)])
    evald = CalibrationData({"rgb": real}, None, f"{len(real)} real DIGIT frames", [str(i) for i in range(len(real))])
    rows = []
    for name, width, k, ckpt in models:
        root = CACHE / "int8_head" / name.split(" ")[0]
        torch.manual_seed(0)
        spec = ModelSpec("rgbmod", width, 1.0 / k)
        fp32 = root / "fp32"
        if not (fp32 / "model.json").is_file():
            source = ckpt if ckpt is not None else ForceNet(build_model("rgbmod", width).eval(), spec)
            export_bundle(source, fp32, ExportOptions(name=f"{name}-fp32", overwrite=True))
        from tactile_force.edge import load_bundle

        fed = evald.for_manifest(load_bundle(fp32).manifest)  # compact graphs read reduced frames
        ref = run_ort(ort_session(fp32.joinpath("model.onnx").read_bytes(), 2), fed)
        for head in (False, True):
            dest = root / ("int8-float-head" if head else "int8-quantized-head")
            if not (dest / "model.json").is_file():
                quantize_bundle(fp32, dest, QuantizeOptions(mode="int8-static", float_head_inputs=head, overwrite=True),
                                calibration=calib, eval_data=evald)
            got = run_ort(ort_session(dest.joinpath("model.onnx").read_bytes(), 2), fed)
            d = np.abs(got - ref)
            p50, p99 = _latency(dest, runs)
            rows.append([name, "float" if head else "int8 (QDQ)", float(d.max()), float(d.mean()),
                         float(np.abs(ref).mean()), p50, p99])
            print(rows[-1], flush=True)
        p50, p99 = _latency(fp32, runs)
        rows.append([name, "fp32 reference", 0.0, 0.0, float(np.abs(ref).mean()), p50, p99])
    return rows


def main(argv: list[str] | None = None) -> int:
    from .machine import describe_machine, header
    from .stats import markdown_table

    argv = sys.argv[1:] if argv is None else argv
    models: list[tuple[str, float, int, Path | None]] = [("rgbmod-w1-s1 (full res, random weights)", 1.0, 1, None)]
    for trained in sorted((CACHE / "distill").glob("*/model.pth")):  # models trained by benchmarks.distill_study
        if "labelled-" in trained.parent.name or "teacher-" in trained.parent.name:
            w, s = trained.parent.name.split("-w")[1].split("-s")
            models.append((f"{trained.parent.name} (trained)", float(w), int(s.split("-")[0]), trained))
    rows = study(models)
    note = ("RGBmod graphs: full resolution with random weights (seed 0), and the models benchmarks.distill_study "
            "trained (if present in benchmarks/cache/distill); int8-static minmax per-channel, calibrated on 64 "
            "virtual DIGIT "
            "frames; errors against the same graph in fp32 on 53 real DIGIT frames (11 AUROVA + 42 FOTS ball "
            "presses); latency of a batch-2 predict, one thread, on a shared machine (other jobs were running).")
    text = header("int8: keeping the head's input in float", "python -m benchmarks.int8_head", describe_machine(), note)
    text += markdown_table(["model", "pooled features + concat", "max abs(int8 - fp32) (N)",
                            "mean abs(int8 - fp32) (N)",
                            "mean abs(fp32 output) (N)", "p50 ms", "p99 ms"], rows, 4) + "\n"
    OUT.write_text(text)
    print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
