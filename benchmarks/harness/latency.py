"""Per-stage latency of what users run: ``ForceRuntime`` driven by an in-memory source.

Each case runs the runtime (one sensor, its contact gate with a background captured from
no-contact frames, the depth stage for depth variants, the model) over pre-rendered virtual
DIGIT frames in contact, read from memory by :class:`~.sources.MemorySource` (back to back:
each frame arrives when the runtime asks for it) or, with ``fps``, by
:class:`~.sources.PacedMemorySource` (frame i due at t0 + i / fps, the source sleeping until
it is: the sensor's cadence, the core idle in between); stage times
are the ones the runtime puts in every reading: source (read()), gate, depth, inference
(the model's ``predict``), total (from the frame's arrival to the finished reading, what a
user's ``total_ms`` shows) and glue = total - gate - depth - inference (the runtime's own
work). For onnxruntime cases the same graph runs in a bare ``InferenceSession.run`` on the
same frames (same session options), one bare run after every runtime step (the same machine
load), so the runtime's overhead over bare inference is a measured figure. p50 / p90 / p99
over ``frames`` readings after ``warmup``.

A case runs its bundle (``LatencyCase.bundle``) in onnxruntime unless a :class:`Predictor`
is given (the engine matrix of docs/benchmarks/latency.md built PyTorch eager, OpenVINO and the
polynomial baseline that way; that page's code was retired at commit 053d257). This module
needs no torch.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from .frames import FramePool, frame_pool, virtual_depth_stage
from .sources import Clock, MemorySource, PacedMemorySource
from .stats import Percentiles, percentiles

STAGES = ("source", "gate", "depth", "inference", "total", "gate+inference", "glue")
ENGINES = ("onnxruntime", "openvino", "torch-eager", "polynomial")
VARIANT_LABEL = {"rgbmod": "RGBmod", "d": "D", "dmod": "Dmod", "rgbmod+d": "RGBmod+D"}


@dataclass(frozen=True)
class ModelConfig:
    """A network: variant, width multiplier, input scale 1/k, residual blocks per stage."""

    variant: str
    width: float
    k: int
    blocks: tuple[int, int, int, int] = (2, 2, 2, 2)

    @property
    def name(self) -> str:
        tag = "" if self.blocks == (2, 2, 2, 2) else "-b" + "".join(str(b) for b in self.blocks)
        return f"{self.variant}-w{self.width:g}-s{self.k}{tag}"  # as benchmarks.reference names it

    @property
    def label(self) -> str:
        size = "full res" if (self.width == 1 and self.k == 1) else f"w{self.width:g}, 1/{self.k}"
        if self.blocks != (2, 2, 2, 2):
            size += ", blocks " + "".join(str(b) for b in self.blocks)
        return f"{VARIANT_LABEL[self.variant]} ({size})"


def parse_config(name: str) -> ModelConfig:
    """'rgbmod-w0.25-s4' / 'rgbmod+d-w1-s1' / 'rgbmod-w0.125-s4-b1111' -> ModelConfig."""
    import re

    m = re.fullmatch(r"(rgbmod|d|dmod|rgbmod\+d)-w([0-9.]+)-s([0-9]+)(?:-b([1-8]{4}))?", name)
    try:
        if m is None:
            raise ValueError(name)
        blocks = tuple(int(c) for c in m.group(4)) if m.group(4) else (2, 2, 2, 2)
        return ModelConfig(m.group(1), float(m.group(2)), int(m.group(3)), blocks)  # type: ignore[arg-type]
    except ValueError:
        raise ValueError(f"model config {name!r}: expected VARIANT-wWIDTH-sK[-bNNNN], e.g. rgbmod-w0.25-s4 or "
                         "rgbmod-w0.125-s4-b1111") from None


@dataclass(frozen=True)
class LatencyCase:
    """One row: what runs (engine: one of ENGINES), its model config (None for the
    polynomial baseline), precision, threads, frames measured, the bundle it runs."""

    config: ModelConfig | None
    precision: str
    engine: str = "onnxruntime"
    threads: int = 1
    frames: int = 1000
    warmup: int = 30
    bundle: Path | None = None

    @property
    def label(self) -> str:
        if self.engine == "polynomial" or self.config is None:
            return "depth polynomial baseline (max deformation, 3rd order)"
        return self.config.label

    @property
    def needs_depth(self) -> bool:
        return self.engine == "polynomial" or self.config is None or self.config.variant != "rgbmod"


@dataclass
class LatencyResult:
    """Percentiles (ms) per stage, GMACs of the model (nan for the baseline), notes; bare:
    the same graph in a bare onnxruntime session on the same frames (onnxruntime cases).
    ``cpu_share``: the process CPU time over the wall time of the measuring loop (1.0 = one
    core busy throughout; several threads can exceed 1). ``missed``: measured frames a paced
    source skipped because the reader was late for them (no reading measured for them; the
    warm-up frames never count), so ``stages[...].n + missed`` is the measured frames."""

    case: LatencyCase
    stages: dict[str, Percentiles]
    gmacs: float = math.nan
    note: str = ""
    bundle: str = ""
    samples: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    bare: Percentiles | None = None
    cpu_share: float = math.nan
    missed: int = 0

    @property
    def overhead(self) -> float:
        """The runtime's own cost over bare inference, p50: (total - gate - depth) / bare - 1."""
        if self.bare is None or not self.bare.n:
            return math.nan
        own = self.samples["total"] - self.samples["gate"] - np.nan_to_num(self.samples["depth"])
        return float(np.percentile(own, 50) / self.bare.p50 - 1.0)


@dataclass
class Predictor:
    """What a case runs: ``model`` (``predict(rgb, depth)``, ``needs_depth``), its GMACs (nan:
    unknown), a note on its weights and where it comes from."""

    model: object
    gmacs: float = math.nan
    note: str = ""
    where: str = ""


def bundle_predictor(case: LatencyCase) -> Predictor:
    """The case's bundle in onnxruntime (``OnnxForceModel``, ``case.threads`` threads)."""
    from tactile_force.edge import OnnxForceModel, load_bundle

    if case.bundle is None:
        raise ValueError(f"LatencyCase({case.label}, {case.precision}).bundle: None; expected a bundle folder "
                         "(benchmarks.latency builds random-weight ones)")
    bundle = load_bundle(case.bundle)
    m = bundle.manifest
    note = "random weights" if "random" in m.provenance.trained_on else "trained"
    return Predictor(OnnxForceModel(bundle, threads=case.threads), float(m.architecture.gmacs or math.nan), note,
                     str(case.bundle))


class BareOnnxRuntime:
    """A graph (``bundle``, default the case's) in a bare ``InferenceSession.run`` (the
    runtime's session options: ``threads`` intra-op threads, sequential, all graph
    optimisations), fed pool frame k; a graph that starts at the network resolution is fed
    the pool's frames reduced beforehand (the session's time only)."""

    def __init__(self, case: LatencyCase, pool: FramePool, bundle: Path | None = None) -> None:
        import onnxruntime as ort
        from tactile_force.edge import load_bundle
        from tactile_force.edge.bundle.manifest import InputKind, Reduction
        from tactile_force.edge.gate.reduce import reduce_frames
        from tactile_force.edge.model.onnx_model import bundle_session_options

        path = bundle or case.bundle
        if path is None:
            raise ValueError(f"BareOnnxRuntime: no bundle for {case.label}, {case.precision}")
        b = load_bundle(path)
        self.sess = ort.InferenceSession(str(b.onnx_path), bundle_session_options(b, case.threads),
                                         providers=["CPUExecutionProvider"])
        self.out = [b.manifest.output.name]
        self.pool = pool
        self.inputs = {}
        for s in b.manifest.inputs:
            full = pool.depth if s.kind is InputKind.DEPTH else pool.rgb
            if s.reduction.method is not Reduction.NONE and full.shape[1:3] != tuple(s.shape[1:3]):
                full = reduce_frames(full, s.reduction)
            self.inputs[s.name] = full

    def run(self, i: int) -> None:
        k = i % len(self.pool.rgb)
        self.sess.run(self.out, {n: x[k:k + 1] for n, x in self.inputs.items()})


def paced(call: Callable[[int], object], n: int, fps: float) -> np.ndarray:
    """``call(i)`` for i < ``n``, one per 1/``fps`` tick, the thread sleeping between them as a
    runtime does between a sensor's frames: ms per call."""
    out = np.empty(n)
    period = 1.0 / fps
    t0 = time.perf_counter() + period
    for i in range(n):
        rest = t0 + i * period - time.perf_counter()
        if rest > 0:
            time.sleep(rest)
        a = time.perf_counter_ns()
        call(i)
        out[i] = (time.perf_counter_ns() - a) / 1e6
    return out


def bare_at_cadence(bare: BareOnnxRuntime, n: int, fps: float) -> np.ndarray:
    """``n`` calls of a bare session at ``fps`` (:func:`paced`): ms per call (the floor no runtime
    around this graph can beat at this cadence on this host)."""
    return paced(bare.run, n, fps)


def auto_trial_frames(fps: float) -> int:
    """Frames at ``fps`` that the runtime's warm-up trial (``RuntimeOptions.prewarm='auto'``,
    edge/runtime/prewarm_decision.py) lasts, with 0.5 s to spare: a measurement of what a user
    gets counts from the runtime's decision on."""
    from tactile_force.edge.runtime.prewarm_decision import PATTERN, SETTLE_NS, WINDOW_NS

    return int((SETTLE_NS + len(PATTERN) * WINDOW_NS) / 1e9 * fps + fps / 2)


def measure(case: LatencyCase, pool: FramePool | None = None, clock: Clock = time.monotonic_ns,
            bare: bool = True, depth: Callable[[], object] | None = None, bare_bundle: Path | None = None,
            predictor: Predictor | None = None, fps: float | None = None) -> LatencyResult:
    """Run ``case`` through ``ForceRuntime`` over the frame pool (cycled) and return
    per-stage percentiles in ms.

    Parameters
    ----------
    case : LatencyCase
        What runs; without ``predictor`` an onnxruntime case on ``case.bundle``.
    pool : FramePool, optional
        Frames in contact (default :func:`~.frames.frame_pool`).
    clock : callable
        The runtime's clock in ns (tests inject one; with ``fps`` it must be
        ``time.monotonic_ns``, the paced source's clock).
    bare : bool
        Also time a graph in a bare onnxruntime session (onnxruntime cases), one bare run
        after every runtime step: the case's own graph, or ``bare_bundle``.
    depth : callable, optional
        The depth-stage factory for depth variants (default: the virtual DIGIT's
        calibration, :func:`~.frames.virtual_depth_stage`).
    predictor : Predictor, optional
        The model the case runs (another engine than onnxruntime).
    fps : float, optional
        Frames per second: frames arrive at this cadence (:class:`~.sources.PacedMemorySource`,
        sleeping until each is due) instead of back to back; the runtime's warm-up trial
        (:func:`auto_trial_frames`) comes on top of the ``warmup`` frames, so the ``frames``
        measured ones count from its decision and take ``frames / fps`` seconds.
    """
    from tactile_force.edge import ContactGate
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor

    if case.engine not in ENGINES:
        raise ValueError(f"LatencyCase.engine={case.engine!r}; expected one of {ENGINES}")
    if predictor is None and case.engine != "onnxruntime":
        raise ValueError(f"LatencyCase.engine={case.engine!r} needs a predictor (a Predictor of that engine)")
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise ValueError(f"measure: fps={fps!r}; expected a finite number > 0")
    if fps is not None and clock is not time.monotonic_ns:
        raise ValueError("measure: fps with an injected clock; a paced source stamps frames with time.monotonic_ns")
    pool = pool or frame_pool()
    cv2.setNumThreads(case.threads)
    p = predictor or bundle_predictor(case)
    gate = ContactGate()
    gate.capture_background(pool.background)
    skip = case.warmup + (auto_trial_frames(fps) if fps is not None else 0)  # frames never measured
    n_total = skip + case.frames
    source = (MemorySource(pool.rgb, n_total, clock) if fps is None
              else PacedMemorySource(pool.rgb, fps, n_total, name="bench", count_from=skip))
    rt = ForceRuntime([Sensor("bench", source, gate)], p.model,
                      RuntimeOptions(threads=case.threads, deadline_ms=1e9, latency_window=16),
                      clock=clock, depth_factory=(depth or virtual_depth_stage) if case.needs_depth else None)
    lat = np.full((n_total, 5), np.nan)
    contact = np.zeros(n_total, bool)

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
    cpu0, wall0 = time.process_time(), time.perf_counter()
    while not rt.finished:
        for r in rt.step():
            keep(r)
        if bare_runner is not None and i < n_total:
            t0 = time.perf_counter_ns()
            bare_runner.run(i)
            bare_ms[i] = (time.perf_counter_ns() - t0) / 1e6
        i += 1
    cpu_s, wall_s = time.process_time() - cpu0, time.perf_counter() - wall0
    rt.close()
    t = lat[skip:]
    samples = {
        "source": t[:, 0],
        "gate": t[:, 1],
        "depth": t[:, 2] if case.needs_depth else np.full(len(t), np.nan),
        "inference": t[:, 3],
        "total": t[:, 4],
    }
    samples["gate+inference"] = samples["gate"] + samples["inference"]
    samples["glue"] = samples["total"] - samples["gate"] - samples["inference"] - np.nan_to_num(samples["depth"])
    n_contact, n_read = int(contact.sum()), int(np.isfinite(lat[:, 4]).sum())
    note = p.note
    if n_contact < n_read:
        note = (note + f"; gate open on {n_contact}/{n_read} frames").strip("; ")
    b = percentiles(bare_ms[skip:]) if bare_runner is not None else None
    return LatencyResult(case, {k: percentiles(v) for k, v in samples.items()}, p.gmacs, note, p.where, samples, b,
                         cpu_s / wall_s if wall_s > 0 else math.nan,
                         source.missed if isinstance(source, PacedMemorySource) else int(source.stats.dropped))
