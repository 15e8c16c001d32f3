"""``tactile-force bench``: does a bundle meet its latency budget on THIS host, and at what error?

What a robot host runs, with the core install only (numpy, onnxruntime, OpenCV; never torch,
onnx or matplotlib): each bundle runs through ``ForceRuntime`` (one sensor, its contact gate,
the depth stage for depth variants, the model) over virtual DIGIT frames in contact read from
memory (:func:`benchmarks.harness.latency.measure`) twice: back to back (each frame there when
the runtime asks, the core never idle) and at the sensor's cadence (frames arriving at ``fps``
per second, the core idle in between, as a user's controller sees them), while the machine is
watched (:class:`benchmarks.harness.machine.CpuWindow`); the under-budget verdict per bundle is
:func:`benchmarks.harness.budget.judge`'s (PASS / OVER_BUDGET / MACHINE_BUSY) on the total p99 at
the cadence (back to back when no cadence is measured, as ``study`` does). With labelled data the
error comes from a replay of that folder through the same runtime ``tactile-force run``
builds, with the same metric code (:func:`tactile_force.edge.data.metrics.readings_error`).

The result is a :class:`BenchReport` (benchmarks/bench_contract.py), written by
benchmarks/bench_report.py as ``report.json`` (a stable contract, see
docs/bench.md), ``report.md`` and ``pareto.png`` (error against p99 latency, the budget line).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from pathlib import Path

from tactile_force.edge.runtime.replay import replay_readings

from .bench_contract import (
    PLOT_PNG,
    REPORT_JSON,
    REPORT_MD,
    SCHEMA,
    STAGES,
    WARMUP,
    BenchError,
    BenchReport,
    BinError,
    BundleResult,
    Cadence,
    Timing,
    _f,
    _timing,
    overall_verdict,
    read_report,
)
from .bench_report import VERDICT_TEXT, cadence_label, markdown, plot, table_rows, text_table, write_json, write_report
from .harness.budget import Attempt
from .harness.frames import contact_frames
from .harness.machine import Machine, MachineState


# ----------------------------------------------------------------------------- what is measured
def _depth_factory(manifest) -> Callable[[], object] | None:
    """The bundle's own depth stage when its manifest records one; None: the virtual DIGIT's
    calibration (:func:`benchmarks.harness.frames.virtual_depth_stage`), which the frames come from."""
    if not manifest.needs_depth or manifest.depth is None:
        return None
    from tactile_force.edge.runtime import build_depth_stage

    return lambda: build_depth_stage(None, manifest)


def replay_error(bundle: Path, data: Path, background: Path | None, threads: int = 1,
                 readings: list | None = None, warn: Callable[[str], None] | None = None) -> BenchError | None:
    """Error of ``bundle`` on the labelled folder ``data`` as ``tactile-force run`` reports it
    (:func:`replay_readings`, then :func:`tactile_force.edge.data.metrics.readings_error`);
    None when no frame got a CNN reading. ``readings``: an earlier replay's, to reuse.

    Raises a TactileForceError subclass (exit 2) when ``data`` or ``background`` is unusable,
    or when ``data`` has no truth (not a labelled folder)."""
    from tactile_force.edge.data.metrics import readings_error
    from tactile_force.edge.errors import DatasetError

    if readings is None:
        readings = replay_readings(bundle, data, background, threads, warn)
    rep, n_truth, missed = readings_error(readings)
    if not n_truth:
        raise DatasetError(f"--data {data}: no frame with a true force (expected the authors' layout: "
                           "images/N.png + forces/force_N.txt, e.g. from 'tactile-force record' or 'synth')")
    if rep is None:
        return None
    o = rep.overall
    return BenchError(o.n, _f(o.re_mean), _f(o.re_std), o.mae_mean, o.mae_std,
                      {k: BinError(s.n, _f(s.re_mean), _f(s.re_std), s.mae_mean, s.mae_std)
                       for k, s in rep.per_bin.items()},
                      str(data), str(background) if background else None, n_truth, missed)


def bench_bundle(path: Path, pool, frames: int = 1000, threads: int = 1, budget_ms: float = 1.0,
                 repeats: int = 3, pause_s: float = 30.0, warmup: int = WARMUP, window=None,
                 sleep: Callable[[float], None] | None = None, fps: float | None = None,
                 cadence_frames: int = 300) -> BundleResult:
    """Latency of one bundle through ``ForceRuntime`` on this host and its verdict.

    Each attempt measures back to back and, with ``fps``, at that cadence right after; the
    verdict is judged on the total p99 at the cadence (back to back without ``fps``).

    Parameters
    ----------
    path : Path
        The bundle folder.
    pool : benchmarks.harness.frames.FramePool
        Frames in contact, read from memory (:func:`contact_frames`).
    frames, warmup : int
        Readings measured back to back, after ``warmup`` readings not counted.
    threads : int
        ONNX Runtime intra-op threads (and OpenCV's).
    budget_ms : float
        The budget for the end-to-end total p99 (ms).
    repeats, pause_s : int, float
        Attempts at most, and the pause before a new one (only after an attempt over budget
        on a busy machine; :func:`benchmarks.harness.budget.judge`).
    fps : float, optional
        Frames per second of the sensor: also measure with frames arriving at this cadence
        (``cadence_frames`` readings after ``warmup``, taking ``(warmup + cadence_frames) / fps``
        seconds) and judge that. None: back to back only.
    cadence_frames : int
        Readings measured at the cadence.

    Returns
    -------
    BundleResult
        ``error`` is None (see :func:`replay_error`).
    """
    import time

    from tactile_force.edge.bundle.graph_facts import bundle_precision
    from tactile_force.edge.bundle.store import load_bundle

    from .harness.budget import JUDGED, judge
    from .harness.latency import BareOnnxRuntime, LatencyCase, ModelConfig, bare_at_cadence, measure
    from .harness.stats import percentiles, too_few_for_p99

    bundle = load_bundle(path)
    m = bundle.manifest
    precision = bundle_precision(bundle.onnx_path)  # what the graph holds, as bundle verify reads it
    scale = m.architecture.input_scale or 1.0
    cfg = ModelConfig(str(m.variant), float(m.architecture.width or 1.0), max(1, round(1.0 / scale)))
    case = LatencyCase(cfg, precision, threads=threads, frames=frames, warmup=warmup, bundle=Path(path))
    depth = _depth_factory(m)

    paced = None if fps is None else replace(case, frames=cadence_frames)
    bare = None if fps is None else BareOnnxRuntime(case, pool)

    def once():
        # warnings about the bench's own frames
        with _quiet("tactile_force.edge.runtime", "tactile_force.edge.gate.contact_gate"):
            r = measure(case, pool, bare=False, depth=depth)
            c = None if paced is None else measure(paced, pool, bare=False, depth=depth, fps=fps)
        floor = None if bare is None or fps is None else percentiles(bare_at_cadence(bare, cadence_frames, fps))
        return (r, c, floor), (c or r).stages[JUDGED].p99

    (result, at_fps, floor), verdict, attempts = judge(once, budget_ms, repeats, pause_s, window,
                                                       sleep or time.sleep)
    s = result.stages
    cadence = None if at_fps is None or fps is None else Cadence(
        float(fps), _timing(at_fps.stages[JUDGED]), _f(at_fps.cpu_share), at_fps.missed,
        None if floor is None else _timing(floor))
    verdict_name, note = verdict.name, result.note
    few = too_few_for_p99(int((at_fps or result).stages[JUDGED].n))
    if few is not None:
        verdict_name, note = "TOO_FEW_READINGS", f"{few}; {note}" if note else few
    opened = re.search(r"gate open on (\d+)/(\d+) frames", note)
    if opened and int(opened.group(1)) < int(opened.group(2)) // 2:
        # most frames gave no force: the times are not the model's; say why instead of judging them
        verdict_name = "NO_READINGS"
        note = f"{note}; no force on most bench frames: {_first_problem(bundle, pool, depth)}"
    if precision != str(m.precision):
        note = (f"{note}; " if note else "") + (f"the manifest says {m.precision} but the graph is {precision} "
                                                "(bundle verify refuses this bundle)")
    stages = {k: _timing(s[k]) for k in STAGES if k in s and (k != "depth" or case.needs_depth)}
    score = m.error_score()
    return BundleResult(
        path=str(path), name=m.name, variant=str(m.variant), precision=precision, total_ms=_timing(s[JUDGED]),
        stages_ms=stages, error=None, manifest_re=_f(score), verdict=verdict_name,
        attempts=attempts, note=note, cadence=cadence)


def _quiet(*names: str):
    """Only errors from these loggers meanwhile (their warnings would be about the bench's own
    virtual frames and background, not the user's sensor)."""
    from tactile_force.edge.report.logs import quiet_loggers

    return quiet_loggers(*names)


def _first_problem(bundle, pool, depth) -> str:
    """Flags and detail of the first reading without a force, over a few bench frames."""
    from tactile_force.edge.gate.contact_gate import ContactGate
    from tactile_force.edge.model.onnx_model import OnnxForceModel
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor

    from .harness.sources import MemorySource

    gate = ContactGate()
    gate.capture_background(pool.background)
    rt = ForceRuntime([Sensor("bench", MemorySource(pool.rgb, 4), gate)], OnnxForceModel(bundle, threads=1),
                      RuntimeOptions(deadline_ms=1e9), depth_factory=depth)
    try:
        while not rt.finished:
            for r in rt.step():
                if r.flags & (Flags.NO_CONTACT | Flags.INVALID_INPUT):
                    return f"{'|'.join(r.flags.names())}: {r.detail}"
    finally:
        rt.close()
    return "unknown"


def run_bench(bundles: Sequence[Path], frames: int = 1000, threads: int = 1, budget_ms: float = 1.0,
              data: Path | None = None, background: Path | None = None, repeats: int = 3, pause_s: float = 30.0,
              show_progress: bool = True, command: str = "", pool=None, window=None,
              sleep: Callable[[float], None] | None = None, fps: float | None = 60.0,
              cadence_frames: int = 300) -> BenchReport:
    """Measure every bundle (latency and verdict; error too with ``data``) into a :class:`BenchReport`.

    Parameters
    ----------
    bundles : sequence of Path
        Bundle folders (e.g. the values of :func:`tactile_force.edge.scene.shipped_bundles`).
    frames, threads, budget_ms, repeats, pause_s, fps, cadence_frames
        As in :func:`bench_bundle` (here ``fps`` defaults to 60, a DIGIT's cadence).
    data, background : Path, optional
        A labelled folder in the authors' layout and its no-contact image: adds the error.
    show_progress : bool
        Draw a progress bar over the bundles (on a terminal).
    command : str
        The command line, recorded in the report.
    pool : FramePool, optional
        Frames in contact (default :func:`contact_frames`).
    """
    import cv2
    from tactile_force.edge.report.progress import progress

    from .harness.machine import describe_machine

    machine = describe_machine()
    pool = pool if pool is not None else contact_frames()
    results = []
    prev = cv2.getNumThreads()
    try:
        for path in progress(list(bundles), desc="bench", enabled=show_progress):
            r = bench_bundle(Path(path), pool, frames, threads, budget_ms, repeats, pause_s, window=window,
                             sleep=sleep, fps=fps, cadence_frames=cadence_frames)
            if data is not None:
                r.error = replay_error(Path(path), Path(data), Path(background) if background else None, threads,
                                       warn=lambda m: print(f"warning: {m}", file=sys.stderr))
            results.append(r)
    finally:
        cv2.setNumThreads(prev)
    from tactile_force.edge import compiled_path

    return BenchReport(SCHEMA, machine, float(budget_ms), int(threads), int(frames),
                       overall_verdict([r.verdict for r in results]), results, command, compiled_path.describe())


__all__ = ["PLOT_PNG", "REPORT_JSON", "REPORT_MD", "SCHEMA", "STAGES", "VERDICT_TEXT", "WARMUP", "Attempt",
           "BenchError", "BenchReport", "BinError", "BundleResult", "Cadence", "Machine", "MachineState", "Timing",
           "bench_bundle", "cadence_label", "contact_frames", "markdown", "overall_verdict", "plot", "read_report",
           "replay_error", "replay_readings", "run_bench", "table_rows", "text_table", "write_json", "write_report"]
