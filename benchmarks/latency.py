"""The latency page (latency.md): every table measured through ``ForceRuntime``, each with the
machine's state while it was measured.

Sections: the hot path per stage (every variant, precision, size, engine); the
engines side by side (PyTorch eager fp32, onnxruntime fp32 / int8, OpenVINO fp32 / int8 on
the same ONNX graphs); two sensors side by side; the demo's late readings; the depth stage
(masked evaluation, mapping speed and its error); the contact gate; graph-level notes.

The measurement itself is :func:`benchmarks.harness.latency.measure`; this module builds
what it runs beyond a bundle in onnxruntime: random-weight bundles of every configuration
(:func:`benchmarks.bundles.latency_bundle`, needs torch), PyTorch eager, OpenVINO and the
polynomial baseline (:func:`measure_case`).

    python -m benchmarks latency [--quick] [--out DIR]
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TypeVar

import cv2
import numpy as np
from tactile_force.edge.runtime.options import ForceModelBase

from .bundles import latency_bundle
from .harness.frames import (
    VIRTUAL_DEPTH_LEVELS_PER_PX,
    VIRTUAL_DEPTH_MAPPING,
    FramePool,
    frame_pool,
)
from .harness.latency import LatencyCase, LatencyResult, ModelConfig, Predictor, bundle_predictor, measure
from .harness.machine import CpuWindow, MachineState, command_line, describe_machine, header
from .harness.paths import shared_data
from .harness.sources import PacedMemorySource
from .harness.stats import Percentiles, markdown_table, percentiles

T = TypeVar("T")


#: The paper's figures, placed beside ours.
PAPER_FIGURES = {
    "RGBmod on an RTX 3060 GPU (paper)": 0.9,
    "RGBmod+D minus RGBmod (paper)": 18.71,
    "GelSight Mini peer (paper's comparison)": 6.0,
}


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
        from tactile_force.edge.depth import MaxDeformationBaseline

        self.model = MaxDeformationBaseline.fit(list(pool.depth), pool.force)

    def predict(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray:
        return np.array([self.model.predict(depth[0])], np.float32)


def predictor(case: LatencyCase, pool: FramePool) -> Predictor:
    """The model a case runs: the polynomial baseline, PyTorch eager (random weights), or the
    case's bundle (a random-weight one built first when it names none) in OpenVINO or
    onnxruntime."""
    from tactile_force.edge import load_bundle

    if case.engine == "polynomial":
        return Predictor(PolynomialBaseline(pool))
    assert case.config is not None, case
    if case.engine == "torch-eager":
        onnx_twin = latency_bundle(case.config, "fp32")
        g = load_bundle(onnx_twin).manifest.architecture.gmacs or math.nan
        return Predictor(TorchEager(case.config, case.threads), g, "random weights", "torch eager (no bundle)")
    path = case.bundle or latency_bundle(case.config, case.precision)
    if case.engine == "openvino":
        m = load_bundle(path).manifest
        model = OpenVinoModel(load_bundle(path).onnx_path, case.threads, m.needs_depth, [s.name for s in m.inputs])
        note = "random weights" if "random" in m.provenance.trained_on else "trained"
        return Predictor(model, float(m.architecture.gmacs or math.nan), note + f"; OpenVINO {model.version}",
                         str(path))
    return bundle_predictor(replace(case, bundle=path))


def measure_case(case: LatencyCase, pool: FramePool | None = None, **kw) -> LatencyResult:
    """:func:`benchmarks.harness.latency.measure` for any engine (keywords passed on); a case
    that names no bundle gets a random-weight one of its configuration and precision."""
    pool = pool or frame_pool()
    if case.engine in ("onnxruntime", "openvino") and case.bundle is None:
        assert case.config is not None, case
        case = replace(case, bundle=latency_bundle(case.config, case.precision))
    return measure(case, pool, predictor=predictor(case, pool), **kw)


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

    data = data or shared_data()
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


NOTES = """Frames: 64 virtual DIGIT frames in contact (18 paper indenters + spheres + a cylinder,
1.5-14.5 N), rendered once, held in memory and read by the runtime through an in-memory
FrameSource (benchmarks.harness.sources.MemorySource), so neither PNG decoding nor rendering is
timed. Each row runs `ForceRuntime` (one sensor, its contact gate with a background captured
from no-contact renders, the depth stage for depth variants, the model) and reads the stage
times every reading carries: gate, depth, inference (the backend's predict), total (frame
arrival -> reading, what `ForceReading.latency.total_ms` shows) and glue (total minus the
stages: the runtime's own work). For onnxruntime rows the same graph also runs in a bare
`InferenceSession.run` on the same frames (same session options), one bare run after every
runtime step so both see the same machine load: "overhead
vs bare" = p50 of (total - gate - depth) over the bare p50, minus 1. Latency bundles have
RANDOM weights (latency does not depend on the values) and are built through export_bundle /
quantize_bundle (int8 calibrated on 32 synthetic frames). Threads = ORT intra-op threads,
OpenVINO inference threads, torch threads and OpenCV threads. Every table states what the
machine did while it was measured (load, CPU clock, the share of the cores other processes
used): p99 is dominated by preemption when it is busy."""


@dataclass
class Section:
    title: str
    body: str
    machine: MachineState | None = None

    def text(self) -> str:
        state = f"\n\nWhile measuring: {self.machine.line()}." if self.machine is not None else ""
        return f"## {self.title}\n\n{self.body}{state}\n"


def _watched(fn: Callable[[], T]) -> tuple[T, MachineState]:
    w = CpuWindow()
    out = fn()
    return out, w.stop()


def two_sensors(bundle: Path, pool, seconds: float) -> tuple[list[list[object]], str]:
    """Each sensor's total latency (p50 / p99, ms) alone and with a second sensor, both at
    60 fps in contact, unsynchronised (the second half a frame later)."""
    from tactile_force.edge import ContactGate, OnnxForceModel
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor

    n = int(seconds * 60)
    rows = []

    def run(names: list[str]) -> dict[str, Percentiles]:
        sensors = []
        for k, name in enumerate(names):
            g = ContactGate()
            g.capture_background(pool.background)
            sensors.append(Sensor(name, PacedMemorySource(pool.rgb, 60.0, n, offset_s=k / 120.0, name=name), g))
        model = OnnxForceModel(bundle, threads=1)  # ForceRuntime.close() closes its model: one per run
        rt = ForceRuntime(sensors, model, RuntimeOptions(latency_window=16))
        got: dict[str, list[float]] = {s: [] for s in names}

        def keep(r) -> None:
            if not r.flags & Flags.STALE and r.frame_index >= 30:
                got[r.sensor].append(r.latency.total_ms)

        rt.run(on_reading=keep)
        rt.close()
        return {s: percentiles(v) for s, v in got.items()}

    one = run(["left"])["left"]
    two = run(["left", "right"])
    rows.append(["one sensor", "left", one.p50, one.p99, one.n, "-"])
    for s, p in two.items():
        rows.append(["two sensors", s, p.p50, p.p99, p.n, f"{100 * (p.p50 / one.p50 - 1):+.0f} %"])
    return rows, (f"{seconds:g} s per run, 60 fps per sensor ({n} frames), the second camera half a frame "
                  f"later; total from each frame's arrival (when the camera stand-in delivered it) to its reading")


def demo_late(bundle: Path) -> list[list[object]]:
    """``tactile-force demo`` (3 grasps, seed 0) headless: readings, late ones, total p50/p99."""
    from tactile_force.edge.cli.demo import run_demo
    from tactile_force.edge.synthetic import VirtualDigitSource

    with tempfile.TemporaryDirectory() as tmp:
        s = run_demo(VirtualDigitSource(seed=0, n_grasps=3, fps=60.0), bundle, tmp, echo=None)
    tot = s.latency_ms.get("total", {})
    return [[int(s.readings), int(s.flags.get("late", 0)), tot.get("p50", math.nan), tot.get("p99", math.nan)]]


def depth_section(pool, frames: int) -> tuple[list[list[object]], list[list[object]]]:
    """Depth stage per mapping in exact mode (every mask pixel vs every 2nd row/column) and
    paper mode (MLP in the dilated mask vs everywhere): p50 / p99 ms and the error against
    evaluating every pixel (mean / max |difference| of the 8-bit depth image inside the mask)."""
    from tactile_force.edge import ContactGate
    from tactile_force.edge.depth import DepthOptions, DepthStage

    cv2.setNumThreads(1)
    g = ContactGate()
    g.capture_background(pool.background)
    masks = [g.update(f).mask.copy() for f in pool.rgb]
    mlp = shared_data("aurova_digit_depth_mlp.npz")

    def timed(st, imgs, ms) -> tuple[Percentiles, list[np.ndarray]]:
        t, out = [], []
        for i in range(frames):
            k = i % len(imgs)
            t0 = time.perf_counter_ns()
            r = st.process(imgs[k], ms[k])
            t.append((time.perf_counter_ns() - t0) / 1e6)
            if i < len(imgs):
                out.append(r.depth[..., 0].astype(np.int16))
        return percentiles(t[5:]), out

    def err(a: list[np.ndarray], b: list[np.ndarray], ms) -> tuple[float, int]:
        d = [np.abs(x - y)[m > 0] for x, y, m in zip(a, b, ms)]
        return float(np.mean([x.mean() for x in d if x.size])), int(max(x.max() for x in d if x.size))

    exact = []
    stages = [("virtual DIGIT LUT (package)",
               lambda step: DepthStage(DepthOptions(VIRTUAL_DEPTH_MAPPING, levels_per_px=VIRTUAL_DEPTH_LEVELS_PER_PX,
                                                    mapping_step=step)))]
    if mlp.is_file():
        stages.append(("paper MLP", lambda step: DepthStage(DepthOptions(mlp, mapping_step=step))))
    mask_px = float(np.mean([np.count_nonzero(m) for m in masks]))
    for name, make in stages:
        p1, d1 = timed(make(1), pool.rgb, masks)
        p2, d2 = timed(make(2), pool.rgb, masks)
        e = err(d1, d2, masks)
        exact.append([name, "exact, every mask pixel", p1.p50, p1.p99, "0 / 0 (the reference)"])
        exact.append([name, "exact, mapping_step 2", p2.p50, p2.p99, f"{e[0]:.2f} / {e[1]}"])
    paper = []
    if mlp.is_file():
        d = shared_data("aurova_digit_grasp")
        imgs = [cv2.imread(str(p)) for p in sorted((d / "images").glob("*.png"))]
        ms = [cv2.imread(str(d / "filt_img_depth" / f"depth_img_{p.stem}.png"), cv2.IMREAD_GRAYSCALE)
              for p in sorted((d / "images").glob("*.png"))]
        ms = [(m > 0).astype(np.uint8) * 255 if m is not None else np.zeros((320, 240), np.uint8) for m in ms]
        res = {}
        for dil in (None, 16, 8):
            st = DepthStage(DepthOptions(mlp, mode="paper", paper_dilation_px=dil))
            st.set_reference(imgs[:1])
            res[dil] = timed(st, imgs, ms)
        for dil in (None, 16, 8):
            p, dd = res[dil]
            e = err(res[None][1], dd, ms) if dil is not None else (0.0, 0)
            what = "every pixel (the authors' way)" if dil is None else f"mask dilated by {dil} px"
            paper.append(["paper MLP, paper mode", what, p.p50, p.p99, f"{e[0]:.2f} / {e[1]}"])
    return exact + paper, [[f"{mask_px:.0f} px ({100 * mask_px / (320 * 240):.0f} % of the frame)"]]


def node_profile(bundle: Path, pool, runs: int) -> tuple[list[list[object]], float]:
    """onnxruntime's own profiler (``SessionOptions.enable_profiling``) over ``runs`` runs of
    the bundle's graph (one thread, the runtime's session options): per op type, the median
    time per run (us), its share of the node time and the node count; and the median
    ``model_run`` time (us)."""
    import json
    from collections import defaultdict

    import onnxruntime as ort
    from tactile_force.edge import load_bundle

    b = load_bundle(bundle)
    with tempfile.TemporaryDirectory() as tmp:
        so = ort.SessionOptions()
        so.intra_op_num_threads = 1
        so.inter_op_num_threads = 1
        so.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
        so.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
        so.log_severity_level = 3
        so.enable_profiling = True
        so.profile_file_prefix = str(Path(tmp) / "ort")
        sess = ort.InferenceSession(str(b.onnx_path), so, providers=["CPUExecutionProvider"])
        name = b.manifest.inputs[0].name
        from tactile_force.edge.bundle.manifest import Reduction
        from tactile_force.edge.gate.reduce import reduce_frames

        red = b.manifest.inputs[0].reduction  # a graph at the network resolution reads reduced frames
        frames = pool.rgb if red.method is Reduction.NONE else reduce_frames(pool.rgb, red)
        for i in range(runs):
            sess.run(None, {name: frames[i % len(frames):i % len(frames) + 1]})
        events = json.loads(Path(sess.end_profiling()).read_text())
    per_run: dict[str, list[float]] = defaultdict(lambda: [0.0] * runs)
    nodes: dict[str, set] = defaultdict(set)
    model_runs = [e["dur"] for e in events if e.get("cat") == "Session" and e.get("name") == "model_run"]
    kernel = [e for e in events if e.get("cat") == "Node" and str(e.get("name", "")).endswith("_kernel_time")]
    for e in kernel:
        nodes[e.get("args", {}).get("op_name", "?")].add(e["name"])
    # Kernel events in order, run after run: every run executes the same node sequence.
    n_nodes = sum(len(v) for v in nodes.values())
    for j, e in enumerate(kernel[: n_nodes * runs]):
        per_run[e.get("args", {}).get("op_name", "?")][j // n_nodes] += e["dur"]
    skip = min(runs // 10, 50)  # warm-up runs
    med = {op: float(np.median(v[skip:])) for op, v in per_run.items()}
    total = sum(med.values()) or 1.0
    rows = [[op, t, f"{100 * t / total:.0f} %", len(nodes[op])] for op, t in sorted(med.items(), key=lambda x: -x[1])]
    return rows, float(np.median(model_runs[skip:])) if model_runs else math.nan


def _ratios(by: dict, quick: bool) -> list[list[object]]:
    rows = []
    for lab in ("RGBmod", "RGBmod+D"):
        for size in ("full res", "w0.25, 1/4"):
            label = f"{lab} ({size})"
            torch_r = by.get((f"{lab} (full res)", "torch-eager", "fp32", 1))
            for prec in ("fp32", "int8-static"):
                ort_r = by.get((label, "onnxruntime", prec, 1))
                ov = by.get((label, "openvino", prec, 1))
                if ort_r is None and ov is None:
                    continue
                t = torch_r.stages["inference"].p50 if torch_r is not None and size == "full res" else math.nan
                o = ort_r.stages["inference"].p50 if ort_r is not None else math.nan
                v = ov.stages["inference"].p50 if ov is not None else math.nan
                rows.append([label, prec, t, o, v, t / o if t == t else None, t / v if t == t else None,
                             v / o if v == v and o == o else None])
    return rows


def latency_page(args, argv: list[str], measure_fn: Callable[[LatencyCase], LatencyResult] = measure_case) -> str:
    """The page's Markdown (``args.quick``: few frames per row, a smoke run)."""
    from .bundles import best_rgbmod_bundle

    quick = bool(args.quick)
    pool = frame_pool()
    sections: list[Section] = []
    results = []
    cases = default_cases(quick)
    w = CpuWindow()
    for i, c in enumerate(cases):
        r = measure_fn(c)
        results.append(r)
        s = r.stages
        print(f"[{i + 1}/{len(cases)}] {c.label} {ENGINE_LABEL[c.engine]} {c.precision} x{c.threads}: gate "
              f"{s['gate'].p50:.3f} depth {s['depth'].p50:.3f} inference {s['inference'].p50:.3f} total p50 "
              f"{s['total'].p50:.3f} p99 {s['total'].p99:.3f} ms", flush=True)
    matrix_state = w.stop()
    by = {(r.case.label, r.case.engine, r.case.precision, r.case.threads): r for r in results}
    sections.append(Section("Hot path per stage, through ForceRuntime (ms)",
                            markdown_table(HEADERS, [result_row(r) for r in results]), matrix_state))
    ratios = _ratios(by, quick)
    sections.append(Section(
        "Engines side by side (same ONNX graphs, same run, inference p50 ms, 1 thread)",
        markdown_table(["model", "precision", "PyTorch eager fp32", "onnxruntime", "OpenVINO", "torch / ORT",
                        "torch / OpenVINO", "OpenVINO / ORT"], ratios, 2)
        + "\n\nPyTorch eager is the paper's way (fp32, full resolution only). OpenVINO runs the bundle's ONNX "
          "graph with a static batch of 1 (the latency hint, one stream); onnxruntime is what the package ships.",
        matrix_state))

    # The default bundle: what the check and users run.
    default_path, which = best_rgbmod_bundle()
    (drow, _), dstate = _watched(lambda: (measure_fn(LatencyCase(COMPACT, "int8-static", frames=300 if quick else 2000,
                                                                  warmup=100, bundle=default_path)), None))
    drow_s = drow.stages
    sections.append(Section(
        f"The default bundle through the runtime ({which})",
        markdown_table(["stage", "p50 ms", "p90 ms", "p99 ms"],
                       [[k, drow_s[k].p50, drow_s[k].p90, drow_s[k].p99] for k in ("source", "gate", "inference",
                                                                                     "glue", "total")])
        + (f"\n\nBare onnxruntime session on the same graph and frames: p50 {drow.bare.p50:.3f}, p99 "
           f"{drow.bare.p99:.3f} ms. The runtime's own overhead over it (p50 of total - gate, over the bare p50): "
           f"{100 * drow.overhead:+.1f} %." if drow.bare is not None else ""), dstate))

    (two_rows, two_note), tstate = _watched(lambda: two_sensors(default_path, pool, 3.0 if quick else 20.0))
    sections.append(Section("Two sensors side by side (default bundle, grabber thread per sensor)",
                            markdown_table(["run", "sensor", "total p50 ms", "total p99 ms", "readings",
                                            "p50 vs one sensor"], two_rows) + "\n\n" + two_note, tstate))

    demo_rows, mstate = _watched(lambda: demo_late(default_path))
    sections.append(Section("`tactile-force demo` (3 grasps, seed 0; the virtual sensor renders ahead, own thread)",
                            markdown_table(["readings", "late (> 16.7 ms from arrival)", "total p50 ms",
                                            "total p99 ms"], demo_rows), mstate))

    (depth_rows, mask_note), dpstate = _watched(lambda: depth_section(pool, 30 if quick else 200))
    sections.append(Section(
        "Depth stage: masked evaluation, mapping speed and its error (one thread)",
        markdown_table(["mapping", "evaluated where", "p50 ms", "p99 ms",
                        "|depth - every pixel| mean / max (8-bit levels, in the mask)"], depth_rows, 3)
        + f"\n\nExact mode runs the mapping only inside the gate's contact mask (mean mask on the latency frames: "
          f"{mask_note[0][0]}); the paper MLP runs in a folded form (fc3 and fc4 have no activation between them: "
          "one 32 -> 3 layer; fc1's position part a per-pixel table), equal to the four layers to 5e-7. Paper mode "
          "(the authors' pipeline, 11 real AUROVA frames, their contact regions as masks) runs the MLP on every pixel "
          "by default; `DepthOptions.paper_dilation_px` runs it only in the dilated mask and takes the reference "
          "frames' gradients elsewhere. The error column compares each depth image with the every-pixel one of the "
          "same mode: paper mode integrates the whole frame, so what lies outside the mask moves the depth inside "
          "it, and the masked variant is not the default.", dpstate))

    gh, gr = gate_table(100 if quick else 500)
    sections.append(Section("Contact gate cost and agreement (ContactGate.update alone)",
                            markdown_table(gh, gr) if gh else "(real data not found: ../shared/data)"))
    (prof, run_us), pstate = _watched(lambda: node_profile(default_path, pool, 100 if quick else 500))
    sections.append(Section(
        "Graph-level work: where the compact int8 RGBmod spends its time",
        "onnxruntime's profiler (`SessionOptions.enable_profiling`), default bundle, one thread, node by node "
        f"(median per run; `model_run` median {run_us:.0f} us, the node times sum to less):\n\n"
        + markdown_table(["op (as onnxruntime runs it)", "us per run", "share of node time", "nodes"], prof, 1)
        + "\n\nThe default graph starts at the network resolution: the frame is reduced to 80 x 60 once, "
        "outside the graph (the runtime's one downscale per frame).",
        pstate))
    paper = markdown_table(["the paper's figure", "ms"], [[k, v] for k, v in PAPER_FIGURES.items()], 2)
    sections.append(Section("The paper's figures (their hardware, not measured here)", paper))

    m = describe_machine()
    text = header("Latency", command_line(argv), m, NOTES)
    text += "\n".join(s.text() for s in sections)
    return text
