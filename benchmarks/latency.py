"""Per-stage latency of the hot path, driving the public API on virtual DIGIT frames in contact.

Stages per frame: source (PNG decode of the frame, what a replay source does), gate
(ContactGate.update), depth (DepthStage.process with the gate's mask; depth variants
only), inference (OnnxForceModel.predict, torch eager, or the depth polynomial), total
(gate + depth + inference + the loop's glue: the cost once a frame is in memory). p50 / p90 /
p99 over ``frames`` after ``warmup``; the gate sees a background captured from no-contact
frames, so every measured frame is in contact (the CNN runs on every frame).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from .bundles import ModelConfig, latency_bundle
from .frames import FramePool, depth_stage, frame_pool
from .stats import Percentiles, percentiles

STAGES = ("source", "gate", "depth", "inference", "total", "gate+inference")
Clock = Callable[[], int]

#: The paper's figures, placed beside ours.
PAPER_FIGURES = {
    "RGBmod on an RTX 3060 GPU (paper)": 0.9,
    "RGBmod+D minus RGBmod (paper)": 18.71,
    "GelSight Mini peer (paper's comparison)": 6.0,
}


@dataclass(frozen=True)
class LatencyCase:
    """One row: what runs (engine: 'onnxruntime' | 'torch-eager' | 'polynomial'), its model
    config (None for the polynomial baseline), precision, threads, frames measured."""

    config: ModelConfig | None
    precision: str
    engine: str = "onnxruntime"
    threads: int = 1
    frames: int = 1000
    warmup: int = 30
    bundle: Path | None = None

    @property
    def label(self) -> str:
        if self.engine == "polynomial":
            return "depth polynomial baseline (max deformation, 3rd order)"
        return self.config.label

    @property
    def needs_depth(self) -> bool:
        return self.engine == "polynomial" or self.config.variant != "rgbmod"


@dataclass
class LatencyResult:
    """Percentiles (ms) per stage, GMACs of the model (nan for the baseline), notes."""

    case: LatencyCase
    stages: dict[str, Percentiles]
    gmacs: float = math.nan
    note: str = ""
    bundle: str = ""
    samples: dict[str, np.ndarray] = field(default_factory=dict, repr=False)


class TorchEager:
    """The paper's way: PyTorch eager fp32 (ForceNet = in-graph preprocessing + ResNet-18)."""

    def __init__(self, cfg: ModelConfig, threads: int, seed: int = 0) -> None:
        import torch

        from tactile_force.export import ForceNet, ModelSpec, build_model

        torch.set_num_threads(threads)
        torch.manual_seed(seed)
        self.torch = torch
        self.net = ForceNet(build_model(cfg.variant, cfg.width), ModelSpec(cfg.variant, cfg.width, 1.0 / cfg.k)).eval()
        self.needs_depth = cfg.variant != "rgbmod"
        self.rgb = cfg.variant in ("rgbmod", "rgbmod+d")

    def predict(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray:
        t = self.torch
        with t.inference_mode():
            xs = ([t.from_numpy(rgb)] if self.rgb else []) + ([t.from_numpy(depth)] if self.needs_depth else [])
            return self.net(*xs).numpy()


class PolynomialBaseline:
    """The classical baseline: max deformation of the depth image -> 3rd-order polynomial (N)."""

    needs_depth = True

    def __init__(self, pool: FramePool) -> None:
        from tactile_force.edge import MaxDeformationBaseline

        self.model = MaxDeformationBaseline.fit(list(pool.depth), pool.force)

    def predict(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray:
        return np.array([self.model.predict(depth[0])], np.float32)


def _predictor(case: LatencyCase, pool: FramePool):
    if case.engine == "polynomial":
        return PolynomialBaseline(pool), math.nan, "", ""
    if case.engine == "torch-eager":
        onnx_twin = latency_bundle(case.config, "fp32")
        from tactile_force.edge import load_bundle

        g = load_bundle(onnx_twin).manifest.architecture.get("gmacs", math.nan)
        return TorchEager(case.config, case.threads), g, "random weights", "torch eager (no bundle)"
    from tactile_force.edge import OnnxForceModel

    path = case.bundle or latency_bundle(case.config, case.precision)
    model = OnnxForceModel(path, threads=case.threads)
    m = model.bundle.manifest
    note = "random weights" if "random" in str(m.provenance.get("trained_on", "")) else "trained"
    return model, float(m.architecture.get("gmacs", math.nan)), note, str(path)


def measure(case: LatencyCase, pool: FramePool | None = None, clock: Clock = time.perf_counter_ns) -> LatencyResult:
    """Run ``case`` over the frame pool (cycled) and return per-stage percentiles in ms."""
    from tactile_force.edge import ContactGate

    pool = pool or frame_pool()
    cv2.setNumThreads(case.threads)
    predictor, gmacs, note, where = _predictor(case, pool)
    gate = ContactGate()
    gate.capture_background(pool.background)
    depth = depth_stage() if case.needs_depth else None
    n_total = case.warmup + case.frames
    t = np.zeros((n_total, 5), np.int64)  # clock stamps: start, decoded, gated, depth, inferred
    t_end = np.zeros(n_total, np.int64)
    rgb = np.empty((1, 320, 240, 3), np.uint8)
    dbuf = np.empty((1, 320, 240, 1), np.uint8)
    contact = 0
    for i in range(n_total):
        png = pool.png[i % len(pool.png)]
        t[i, 0] = clock()
        frame = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)
        t[i, 1] = clock()
        g = gate.update(frame)
        t[i, 2] = clock()
        contact += bool(g.contact)
        d = None
        if depth is not None:
            res = depth.process(frame, g.mask)
            dbuf[0] = res.depth
            d = dbuf
        t[i, 3] = clock()
        rgb[0] = frame
        predictor.predict(rgb, d)
        t[i, 4] = clock()
        t_end[i] = t[i, 4]
    t = t[case.warmup:].astype(np.float64) / 1e6
    samples = {
        "source": t[:, 1] - t[:, 0],
        "gate": t[:, 2] - t[:, 1],
        "depth": t[:, 3] - t[:, 2] if depth is not None else np.full(len(t), np.nan),
        "inference": t[:, 4] - t[:, 3],
        "total": t[:, 4] - t[:, 1],
    }
    samples["gate+inference"] = samples["gate"] + samples["inference"]
    if contact < n_total:
        note = (note + f"; gate open on {contact}/{n_total} frames").strip("; ")
    return LatencyResult(case, {k: percentiles(v) for k, v in samples.items()}, gmacs, note, where, samples)


# ----------------------------------------------------------------------------- the matrix

COMPACT = ModelConfig("rgbmod", 0.25, 4)
VARIANTS = ("rgbmod", "d", "dmod", "rgbmod+d")


def default_cases(quick: bool = False) -> list[LatencyCase]:
    """The latency matrix. Full-resolution rows use fewer frames (they take 20-200 ms each)."""
    n = 100 if quick else 1000
    slow_int8 = 30 if quick else 200
    slow_fp = 20 if quick else 100
    cases: list[LatencyCase] = []
    # Compact sizes of RGBmod, int8 static, one thread (how the default was chosen).
    for w, k in ((0.25, 4), (0.125, 8), (0.25, 8), (0.5, 4), (0.25, 2), (0.5, 2)):
        if quick and (w, k) not in ((0.25, 4), (0.125, 8)):
            continue
        cases.append(LatencyCase(ModelConfig("rgbmod", w, k), "int8-static", frames=n))
    # Every variant at the compact size, every precision, 1 and 2 threads for int8.
    for v in VARIANTS:
        cfg = ModelConfig(v, 0.25, 4)
        for p in ("fp32", "int8-static", "int8-dynamic", "fp16"):
            if cfg == COMPACT and p == "int8-static":
                pass  # already above
            else:
                cases.append(LatencyCase(cfg, p, frames=n))
            if p in ("int8-static", "fp32") and not quick:
                cases.append(LatencyCase(cfg, p, threads=2, frames=n))
    cases.append(LatencyCase(None, "fp64", engine="polynomial", frames=n))
    # Full resolution (the paper's network), our way and the paper's way.
    for v in (("rgbmod", "rgbmod+d") if quick else VARIANTS):
        full = ModelConfig(v, 1.0, 1)
        cases.append(LatencyCase(full, "int8-static", frames=slow_int8, warmup=5))
        if v in ("rgbmod", "rgbmod+d"):
            cases.append(LatencyCase(full, "fp32", frames=slow_fp, warmup=3))
            cases.append(LatencyCase(full, "fp32", engine="torch-eager", frames=slow_fp, warmup=3))
            if not quick:
                cases.append(LatencyCase(full, "int8-static", threads=2, frames=slow_int8, warmup=5))
    return cases


def result_row(r: LatencyResult) -> list[object]:
    c = r.case
    s = r.stages
    eng = {"onnxruntime": "ORT", "torch-eager": "torch eager", "polynomial": "numpy"}[c.engine]
    cells: list[object] = [c.label, f"{eng} {c.precision}", c.threads, s["total"].n, r.gmacs if r.gmacs == r.gmacs else None]
    cells.append(s["source"].p50)
    for k in ("gate", "depth", "inference", "total"):
        p = s[k]
        cells.append(f"{p.p50:.3f} / {p.p90:.3f} / {p.p99:.3f}" if p.n else "-")
    cells.append(r.note)
    return cells


HEADERS = ["model", "engine, precision", "threads", "frames", "GMACs", "decode p50",
           "gate p50/p90/p99", "depth p50/p90/p99", "inference p50/p90/p99", "total p50/p90/p99", "weights / notes"]


def gate_table(repeats: int = 500, data: Path | None = None) -> tuple[list[str], list[list[object]]]:
    """Gate cost per DIGIT frame at downscale 1/2/4 and the masks' agreement (was bench_gate.py):
    IoU with full resolution on the 11 AUROVA frames and with the labelled GelSight Mini circles."""
    from tactile_force.edge import ContactGate, GateOptions

    from .frames import REPO

    data = data or REPO.parent / "shared" / "data"
    bg = cv2.imread(str(data / "digit_backgrounds" / "aurova_background_b.png"))
    imgs = sorted((data / "aurova_digit_grasp" / "images").glob("*.png"))
    if bg is None or not imgs:
        return [], []
    frames = [cv2.imread(str(p)) for p in imgs]
    z = np.load(data / "gelsight_mini_ball_presses.npz")
    yy, xx = np.mgrid[:480, :640]
    masks: dict[int, list[np.ndarray]] = {}
    rows = []
    cv2.setNumThreads(1)
    for ds in (1, 2, 4):
        g = ContactGate(GateOptions(downscale=ds))
        g.capture_background([bg])
        masks[ds] = []
        for f in frames:
            gg = ContactGate(GateOptions(downscale=ds))
            gg.capture_background([bg])
            masks[ds].append(gg.update(f).mask > 0)
        img = frames[len(frames) // 2]
        for _ in range(50):
            g.update(img)
        t = []
        for _ in range(repeats):
            t0 = time.perf_counter_ns()
            g.update(img)
            t.append((time.perf_counter_ns() - t0) / 1e6)
        ious = []
        for im, (cx, cy), r in zip(z["imgs"], z["touch_center"].astype(float), z["touch_radius"].astype(float)):
            gg = ContactGate(GateOptions.gelsight_mini(downscale=ds))
            gg.capture_background([z["f0"]])
            m = gg.update(im).mask > 0
            lab = (xx - cx) ** 2 + (yy - cy) ** 2 <= r * r
            ious.append((m & lab).sum() / (m | lab).sum())
        p = percentiles(t)
        rows.append([ds, p.p50, p.p90, p.p99, ious and float(np.mean(ious))])
    for row, ds in zip(rows, (1, 2, 4)):
        iou = [(a & b).sum() / max(1, (a | b).sum()) for a, b in zip(masks[1], masks[ds])]
        found = sum(int(m.any()) for m in masks[ds])
        row += [f"{np.mean(iou):.3f} (min {np.min(iou):.3f})", f"{found}/{len(frames)}"]
    headers = ["downscale", "gate p50 ms", "p90 ms", "p99 ms", "GelSight Mini IoU vs labels (mean)",
               "AUROVA IoU vs full res, mean (min)", "AUROVA frames with a mask"]
    return headers, rows
