"""Per-stage latency of what users run: ``ForceRuntime`` driven by an in-memory source.

Each case runs the runtime (one sensor, its contact gate with a background captured from
no-contact frames, the depth stage for depth variants, the model) over pre-rendered virtual
DIGIT frames in contact, read from memory by :class:`MemorySource`; stage times are the ones
the runtime puts in every reading: source (read()), gate, depth, inference (the model's
``predict``), total (from the frame's arrival to the finished reading, what a user's
``total_ms`` shows) and glue = total - gate - depth - inference (the runtime's own work).
For onnxruntime cases the same graph runs in a bare ``InferenceSession.run`` on the same
frames (same session options), one bare run after every runtime step (the same machine load),
so the runtime's overhead over bare inference is a measured figure. p50 / p90 / p99 over
``frames`` readings after ``warmup``.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np
from tactile_force.edge.frames import FrameSource, TimedFrame
from tactile_force.edge.runtime.options import ForceModelBase

from .bundles import ModelConfig, latency_bundle
from .frames import FramePool, depth_stage, frame_pool
from .stats import Percentiles, percentiles

STAGES = ("source", "gate", "depth", "inference", "total", "gate+inference", "glue")
ENGINES = ("onnxruntime", "openvino", "torch-eager", "polynomial")
Clock = Callable[[], int]

#: The paper's figures, placed beside ours.
PAPER_FIGURES = {
    "RGBmod on an RTX 3060 GPU (paper)": 0.9,
    "RGBmod+D minus RGBmod (paper)": 18.71,
    "GelSight Mini peer (paper's comparison)": 6.0,
}


@dataclass(frozen=True)
class LatencyCase:
    """One row: what runs (engine: one of ENGINES), its model config (None for the
    polynomial baseline), precision, threads, frames measured."""

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
    """Percentiles (ms) per stage, GMACs of the model (nan for the baseline), notes; bare:
    the same graph in a bare onnxruntime session on the same frames (onnxruntime cases)."""

    case: LatencyCase
    stages: dict[str, Percentiles]
    gmacs: float = math.nan
    note: str = ""
    bundle: str = ""
    samples: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    bare: Percentiles | None = None

    @property
    def overhead(self) -> float:
        """The runtime's own cost over bare inference, p50: (total - gate - depth) / bare - 1."""
        if self.bare is None or not self.bare.n:
            return math.nan
        own = self.samples["total"] - self.samples["gate"] - np.nan_to_num(self.samples["depth"])
        return float(np.percentile(own, 50) / self.bare.p50 - 1.0)


class MemorySource(FrameSource):
    """A FrameSource over frames already in memory (cycled ``n`` times in all): what the
    runtime reads when decoding or rendering is not part of the measurement. Each frame
    arrives when read() is called (``arrival_ns``)."""

    name = "memory"

    def __init__(self, frames: np.ndarray, n: int, clock: Clock = time.monotonic_ns) -> None:
        super().__init__()
        self.frames, self.n, self.clock = frames, n, clock

    def read(self) -> TimedFrame | None:
        i = self.stats.frames
        if i >= self.n:
            return None
        self.stats.frames += 1
        now = self.clock()
        return TimedFrame(self.frames[i % len(self.frames)], now, i, arrival_ns=now)


class ListSource(FrameSource):
    """A finite FrameSource over frames in memory, each read once, with its true force (N;
    None = unknown or cannot be judged): what the error, trust and stability benchmarks feed
    the runtime. Each frame arrives when read() is called (``arrival_ns``)."""

    name = "memory"

    def __init__(self, frames: Sequence[np.ndarray] | np.ndarray, truth: Sequence[float | None] | None = None,
                 clock: Clock = time.monotonic_ns) -> None:
        super().__init__()
        self.frames, self.clock = frames, clock
        self.truth: list[float | None] = list(truth) if truth is not None else [None] * len(frames)

    def read(self) -> TimedFrame | None:
        i = self.stats.frames
        if i >= len(self.frames):
            return None
        self.stats.frames += 1
        now = self.clock()
        return TimedFrame(self.frames[i], now, i, self.truth[i], arrival_ns=now)


class TorchEager(ForceModelBase):
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
            return self.net(*xs).numpy().reshape(-1)


class OpenVinoModel(ForceModelBase):
    """The same ONNX graph on OpenVINO's CPU plugin (latency hint, one stream, ``threads``
    inference threads, static batch 1). Needs the optional ``openvino`` package (bench extra)."""

    def __init__(self, onnx_path: Path, threads: int, needs_depth: bool, inputs: list[str]) -> None:
        import openvino as ov

        core = ov.Core()
        model = core.read_model(str(onnx_path))
        shapes = {name: [1, 320, 240, 1 if name == "depth" else 3] for name in inputs}
        model.reshape({model.input(n): s for n, s in shapes.items()})
        self.compiled = core.compile_model(model, "CPU", {"INFERENCE_NUM_THREADS": threads, "NUM_STREAMS": 1,
                                                          "PERFORMANCE_HINT": "LATENCY"})
        self.request = self.compiled.create_infer_request()
        self.inputs = inputs
        self.needs_depth = needs_depth
        self.version = ov.__version__ if hasattr(ov, "__version__") else ov.get_version()

    def predict(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray:
        feed = {n: (depth if n == "depth" else rgb) for n in self.inputs}
        out = self.request.infer(feed, share_inputs=True)
        return np.asarray(next(iter(out.values())), np.float32).reshape(-1)


class PolynomialBaseline(ForceModelBase):
    """The classical baseline: max deformation of the depth image -> 3rd-order polynomial (N)."""

    needs_depth = True

    def __init__(self, pool: FramePool) -> None:
        from tactile_force.edge import MaxDeformationBaseline

        self.model = MaxDeformationBaseline.fit(list(pool.depth), pool.force)

    def predict(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray:
        return np.array([self.model.predict(depth[0])], np.float32)


def _predictor(case: LatencyCase, pool: FramePool):
    """(model, GMACs, note, where) for a case."""
    if case.engine not in ENGINES:
        raise ValueError(f"LatencyCase.engine={case.engine!r}; expected one of {ENGINES}")
    if case.engine == "polynomial":
        return PolynomialBaseline(pool), math.nan, "", ""
    from tactile_force.edge import load_bundle

    if case.engine == "torch-eager":
        onnx_twin = latency_bundle(case.config, "fp32")
        g = load_bundle(onnx_twin).manifest.architecture.gmacs or math.nan
        return TorchEager(case.config, case.threads), g, "random weights", "torch eager (no bundle)"
    path = case.bundle or latency_bundle(case.config, case.precision)
    bundle = load_bundle(path)
    m = bundle.manifest
    note = "random weights" if "random" in m.provenance.trained_on else "trained"
    gmacs = float(m.architecture.gmacs or math.nan)
    if case.engine == "openvino":
        model = OpenVinoModel(bundle.onnx_path, case.threads, m.needs_depth, [s.name for s in m.inputs])
        return model, gmacs, note + f"; OpenVINO {model.version}", str(path)
    from tactile_force.edge import OnnxForceModel

    return OnnxForceModel(bundle, threads=case.threads), gmacs, note, str(path)


class BareOnnxRuntime:
    """The case's graph (or ``bundle``: e.g. the reference graph of issue 18) in a bare
    ``InferenceSession.run`` (the runtime's session options: ``threads`` intra-op threads,
    sequential, all graph optimisations), fed pool frame k; a graph that starts at the network
    resolution is fed the pool's frames reduced beforehand (the session's time only)."""

    def __init__(self, case: LatencyCase, pool: FramePool, bundle: Path | None = None) -> None:
        import onnxruntime as ort
        from tactile_force.edge import load_bundle
        from tactile_force.edge.bundle.manifest import InputKind, Reduction
        from tactile_force.edge.gate.reduce import reduce_frames

        bundle = load_bundle(bundle or case.bundle or latency_bundle(case.config, case.precision))
        so = ort.SessionOptions()
        so.intra_op_num_threads = case.threads
        so.inter_op_num_threads = 1
        so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        so.log_severity_level = 3
        self.sess = ort.InferenceSession(str(bundle.onnx_path), so, providers=["CPUExecutionProvider"])
        self.kinds = {s.name: s.kind for s in bundle.manifest.inputs}
        self.out = [bundle.manifest.output.name]
        self.pool = pool
        self.inputs = {}
        for s in bundle.manifest.inputs:
            full = pool.depth if s.kind is InputKind.DEPTH else pool.rgb
            if s.reduction.method is not Reduction.NONE and full.shape[1:3] != tuple(s.shape[1:3]):
                full = reduce_frames(full, s.reduction)
            self.inputs[s.name] = full

    def run(self, i: int) -> None:
        k = i % len(self.pool.rgb)
        self.sess.run(self.out, {n: x[k:k + 1] for n, x in self.inputs.items()})


def measure(case: LatencyCase, pool: FramePool | None = None, clock: Clock = time.monotonic_ns,
            bare: bool = True, depth: Callable[[], object] | None = None,
            bare_bundle: Path | None = None) -> LatencyResult:
    """Run ``case`` through ``ForceRuntime`` over the frame pool (cycled) and return
    per-stage percentiles in ms; ``bare``: also time a graph in a bare onnxruntime session
    (onnxruntime cases), one bare run after every runtime step: the case's own graph, or
    ``bare_bundle`` (issue 18: the reference graph of commit c1733e6). ``clock`` is the
    runtime's clock (tests inject one).
    ``depth``: the depth-stage factory for depth variants (default: the virtual DIGIT's
    calibration, :func:`benchmarks.frames.depth_stage`)."""
    from tactile_force.edge import ContactGate
    from tactile_force.edge.runtime.loop import ForceRuntime, RuntimeOptions, Sensor

    pool = pool or frame_pool()
    cv2.setNumThreads(case.threads)
    predictor, gmacs, note, where = _predictor(case, pool)
    gate = ContactGate()
    gate.capture_background(pool.background)
    n_total = case.warmup + case.frames
    source = MemorySource(pool.rgb, n_total, clock)
    rt = ForceRuntime([Sensor("bench", source, gate)], predictor,
                      RuntimeOptions(threads=case.threads, deadline_ms=1e9, latency_window=16),
                      clock=clock, depth_factory=(depth or depth_stage) if case.needs_depth else None)
    lat = np.full((n_total, 5), np.nan)
    contact = np.zeros(n_total, bool)
    from tactile_force.edge.reading import Flags

    def keep(r) -> None:
        if r.frame_index >= 0 and not r.flags & Flags.STALE:
            L = r.latency
            lat[r.frame_index] = (L.source_ms, L.gate_ms, L.depth_ms, L.inference_ms, L.total_ms)
            contact[r.frame_index] = not (r.flags & (Flags.NO_CONTACT | Flags.INVALID_INPUT))

    # A bare session run of the same graph follows every runtime step (onnxruntime cases):
    # both see the same machine load, interleaved frame by frame.
    bare_runner = BareOnnxRuntime(case, pool, bare_bundle) if bare and case.engine == "onnxruntime" else None
    bare_ms = np.full(n_total, np.nan)
    i = 0
    while not rt.finished:
        for r in rt.step():
            keep(r)
        if bare_runner is not None and i < n_total:
            t0 = time.perf_counter_ns()
            bare_runner.run(i)
            bare_ms[i] = (time.perf_counter_ns() - t0) / 1e6
        i += 1
    rt.close()
    t = lat[case.warmup:]
    samples = {
        "source": t[:, 0],
        "gate": t[:, 1],
        "depth": t[:, 2] if case.needs_depth else np.full(len(t), np.nan),
        "inference": t[:, 3],
        "total": t[:, 4],
    }
    samples["gate+inference"] = samples["gate"] + samples["inference"]
    samples["glue"] = samples["total"] - samples["gate"] - samples["inference"] - np.nan_to_num(samples["depth"])
    n_contact = int(contact.sum())
    if n_contact < n_total:
        note = (note + f"; gate open on {n_contact}/{n_total} frames").strip("; ")
    b = percentiles(bare_ms[case.warmup:]) if bare_runner is not None else None
    return LatencyResult(case, {k: percentiles(v) for k, v in samples.items()}, gmacs, note, where, samples, b)


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
    if openvino_available():
        cases += openvino_cases(quick)
    return cases


def openvino_available() -> bool:
    try:
        import openvino  # noqa: F401
    except ImportError:
        return False
    return True


def openvino_cases(quick: bool = False) -> list[LatencyCase]:
    """OpenVINO on the same ONNX graphs as the onnxruntime rows: compact and full-resolution
    RGBmod and RGBmod+D, fp32 and int8 static, one thread."""
    out = []
    for v in ("rgbmod", "rgbmod+d"):
        for w, k, n, warm in ((0.25, 4, 100 if quick else 1000, 30), (1.0, 1, 20 if quick else 100, 3)):
            for p in ("fp32", "int8-static"):
                out.append(LatencyCase(ModelConfig(v, w, k), p, engine="openvino", frames=n, warmup=warm))
    return out


def result_row(r: LatencyResult) -> list[object]:
    c = r.case
    s = r.stages
    eng = ENGINE_LABEL[c.engine]
    gmacs = r.gmacs if r.gmacs == r.gmacs else None
    cells: list[object] = [c.label, f"{eng} {c.precision}", c.threads, s["total"].n, gmacs]
    for k in ("gate", "depth", "inference", "total"):
        p = s[k]
        cells.append(f"{p.p50:.3f} / {p.p90:.3f} / {p.p99:.3f}" if p.n else "-")
    cells.append(s["glue"].p50)
    cells.append(r.bare.p50 if r.bare is not None else None)
    cells.append(f"{100 * r.overhead:+.0f} %" if math.isfinite(r.overhead) else "-")
    cells.append(r.note)
    return cells


ENGINE_LABEL = {"onnxruntime": "ORT", "openvino": "OpenVINO", "torch-eager": "torch eager", "polynomial": "numpy"}
HEADERS = ["model", "engine, precision", "threads", "frames", "GMACs", "gate p50/p90/p99", "depth p50/p90/p99",
           "inference p50/p90/p99", "total p50/p90/p99", "glue p50", "bare ORT p50", "overhead vs bare",
           "weights / notes"]


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
