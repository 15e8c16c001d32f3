"""Latency at the sensor's cadence (cadence.md): what a reading costs when frames arrive every
1/60 s, measured against a bare model call at the same cadence in the same process.

Reference: a bare onnxruntime session (1 intra-op thread, sequential) on the shipped default
graph, fed the runtime's reduced contact frames, one call per 1/60 s tick, sleeping between
calls. Each round runs, in this order, a reference phase before every runtime phase:
``ForceRuntime`` with the default bundle and one sensor (warm-ups off, forced on, then as the
runtime decides on this host: ``RuntimeOptions.prewarm='auto'``, the default, measured once it
has decided) and with eight sensors phase-shifted by 1/480 s (the same three); every sensor's
frames arrive at 60 fps from
:class:`~.harness.sources.PacedMemorySource`. Ratios divide by the reference p50 of the same
round, so the machine's speed cancels. One back-to-back phase per round gives the floor the
cold time is measured against (where it goes, per stage). Beside each reference phase a floor
phase at the same cadence: the frame's one downscale (the gate's reduction, the network's
input, into a buffer made once) and then the bare call on that image: the least any runtime that
reads a sensor's frame adds to the bare call (:class:`DownscaleThenBare`). ``tactile-force
bench``'s verdict at the cadence on the default bundle is counted over ``--bench-runs`` runs.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

import numpy as np

from .harness.frames import contact_frames
from .harness.latency import BareOnnxRuntime, LatencyCase, auto_trial_frames, bare_at_cadence, paced
from .harness.machine import CpuWindow, command_line, describe_machine, header
from .harness.sources import MemorySource, PacedMemorySource
from .harness.stats import markdown_table

FPS = 60.0
HAND = 8  # sensors of the many-sensor phases
SKIP = 20  # readings per sensor not counted (the runtime's first frames)
STAGES = ("gate", "inference", "glue", "total")


@dataclass
class Phase:
    """One measured phase: per-sensor total latency (ms), per-stage samples (ms), the process
    CPU time and wall time (s), readings, warm-ups run and frames that waited for one."""

    totals: list[np.ndarray]
    stages: dict[str, np.ndarray]
    cpu_s: float
    wall_s: float
    readings: int
    prewarms: int = 0
    overran: int = 0
    workers: int = 1  # threads that ran a step's per-sensor work (RuntimeOptions.workers)
    state: str = ""

    @property
    def cpu_share(self) -> float:
        return self.cpu_s / self.wall_s if self.wall_s > 0 else math.nan

    @property
    def cpu_per_reading_ms(self) -> float:
        return 1e3 * self.cpu_s / self.readings if self.readings else math.nan

    def p(self, q: float, worst: bool = False) -> float:
        """Total latency percentile q (ms): of all readings, or the worst sensor's."""
        if worst:
            return max(float(np.percentile(t, q)) for t in self.totals)
        return float(np.percentile(np.concatenate(self.totals), q))


def runtime_phase(model, pool, sensors: int, n: int, prewarm: Literal["auto", True, False],
                  fps: float | None = FPS, workers: int | None = None, shifted: bool = True) -> Phase:
    """``ForceRuntime`` over ``sensors`` in-memory sensors, ``n`` frames each: at ``fps``
    (phase-shifted by 1/(fps x sensors); ``shifted`` False: all in phase, as synchronised
    cameras) or back to back (``fps`` None); ``workers`` as ``RuntimeOptions.workers``
    (None: auto, two on a host with two cores or more). With ``prewarm`` 'auto' the frames
    (and the CPU time) count from when the runtime has decided whether warm-ups pay (its
    trial's frames come on top)."""
    from tactile_force.edge import ContactGate
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
    trial = auto_trial_frames(fps or FPS) if prewarm == "auto" else 0
    made = []
    for k in range(sensors):
        gate = ContactGate()
        gate.capture_background(pool.background)
        total = n + SKIP + trial
        offset = 0.05 + (k / (fps * sensors) if shifted and fps else 0.0)
        src = (MemorySource(pool.rgb, total) if fps is None
               else PacedMemorySource(pool.rgb, fps, total, offset_s=offset, name=f"s{k}"))
        made.append(Sensor(f"s{k}", src, gate))
    rt = ForceRuntime(made, model, RuntimeOptions(deadline_ms=1e9, prewarm=prewarm, workers=workers),
                       owns_model=False)
    rt.start(1.0)
    first = -1 if trial else SKIP  # -1: set once the runtime has decided whether warm-ups pay
    rows: dict[str, list[tuple[float, ...]]] = {s.name: [] for s in made}
    count = 0
    c0, w0 = time.process_time(), time.perf_counter()
    while not rt.finished:
        readings = rt.step()
        if first < 0 and rt.stats.prewarm != "trying":  # decided: count from here
            first = max(SKIP, 1 + max(r.frame_index for r in readings) if readings else 0)
            count, c0, w0 = 0, time.process_time(), time.perf_counter()
        for r in readings:
            count += 1
            if r.frame_index >= first >= 0:
                L = r.latency
                rows[r.sensor].append((L.source_ms, L.gate_ms, L.inference_ms, L.total_ms))
    cpu_s, wall_s = time.process_time() - c0, time.perf_counter() - w0
    rt.close()
    a = np.array([x for v in rows.values() for x in v])
    stages = {"source": a[:, 0], "gate": a[:, 1], "inference": a[:, 2], "total": a[:, 3],
              "glue": a[:, 3] - a[:, 1] - a[:, 2]}
    return Phase([np.array([x[3] for x in v]) for v in rows.values()], stages, cpu_s, wall_s, count,
                 rt.stats.prewarms, rt.stats.prewarm_overran, rt.workers, rt.stats.prewarm)


class DownscaleThenBare:
    """The floor under a runtime at the cadence: per call the pool frame's one downscale by the gate's
    own reduction (edge/gate/frame_work.py: the compiled kernel where this process has it, else
    OpenCV; the image the runtime hands the network) into a buffer made once, then the bare call of
    ``bare``'s graph on it. ``path``: which reduction ran."""

    def __init__(self, bare: BareOnnxRuntime, pool) -> None:
        from tactile_force.edge.gate import GateOptions
        from tactile_force.edge.gate.frame_work import FrameWork

        o = GateOptions()
        self.work = FrameWork(pool.rgb[0].shape, o.downscale, o.blur, o.threshold)
        (self.name,) = bare.inputs  # the default bundle: one reduced RGB input
        self.bare, self.frames = bare, pool.rgb
        self.feed = {self.name: self.work.small[None]}
        self.path = "compiled kernel" if self.work._k is not None else "OpenCV"

    def __call__(self, i: int) -> None:
        self.work.reduce(self.frames[i % len(self.frames)])
        self.bare.sess.run(self.bare.out, self.feed)


@dataclass
class Round:
    """One round: the reference calls (ms), the floor calls (ms: :class:`DownscaleThenBare`) and the
    runtime phases by name."""

    ref: np.ndarray
    phases: dict[str, Phase] = field(default_factory=dict)
    floor: np.ndarray = field(default_factory=lambda: np.empty(0))

    def ratio(self, name: str, q: float, worst: bool = False) -> float:
        return self.phases[name].p(q, worst) / float(np.median(self.ref))


PHASES: dict[str, tuple[int, Literal["auto", True, False]]] = {
    "1 sensor, before": (1, False), "1 sensor, forced on": (1, True), "1 sensor, after": (1, "auto"),
    f"{HAND} sensors, before": (HAND, False), f"{HAND} sensors, forced on": (HAND, True),
    f"{HAND} sensors, after": (HAND, "auto")}


def setup():
    """The frames in contact, a bare session and the runtime's model of the default bundle,
    OpenCV on one thread as a scene with ``threads = 1`` runs (edge/scene/build.py)."""
    import cv2
    from tactile_force.edge import OnnxForceModel, load_bundle
    from tactile_force.edge.scene import default_bundle_path

    cv2.setNumThreads(1)
    pool = contact_frames()
    path = default_bundle_path()
    bare = BareOnnxRuntime(LatencyCase(None, "fp32", bundle=path), pool)
    return pool, bare, OnnxForceModel(load_bundle(path), threads=1)


def measure(rounds: int, n: int) -> tuple[list[Round], str]:
    """``rounds`` rounds of every phase, ``n`` frames a sensor each; and which reduction the floor ran."""
    pool, bare, model = setup()
    out = []
    floor: DownscaleThenBare | None = None
    for k in range(rounds):
        rd = Round(np.empty(0))
        rd.phases["back to back"] = runtime_phase(model, pool, 1, 2000, prewarm=True, fps=None)
        floor = floor or DownscaleThenBare(bare, pool)  # after a gate asked for the kernels
        refs, floors = [], []
        for name, (sensors, prewarm) in PHASES.items():
            refs.append(bare_at_cadence(bare, n, FPS))
            floors.append(paced(floor, n, FPS))
            rd.phases[name] = runtime_phase(model, pool, sensors, n, prewarm)
        rd.ref, rd.floor = np.concatenate(refs), np.concatenate(floors)
        out.append(rd)
        print(f"cadence round {k + 1}/{rounds}: reference p50 {np.median(rd.ref):.3f} ms; 1 sensor p50 / reference "
              f"{rd.ratio('1 sensor, before', 50):.2f} before, {rd.ratio('1 sensor, after', 50):.2f} after",
              flush=True)
    model.close()
    return out, floor.path if floor is not None else "-"


def bench_passes(runs: int, bundle: Path | None = None) -> list:
    """``tactile-force bench --bundle <bundle> --repeats 1`` at 60 fps, ``runs`` times: the
    :class:`~.bench.BundleResult` of each (its verdict, and the bundle's graph alone at the
    cadence: ``cadence.bare_ms``). ``bundle``: the shipped default when None."""
    from tactile_force.edge.scene import default_bundle_path

    from .bench import bench_bundle

    pool = contact_frames()
    path = bundle or default_bundle_path()
    return [bench_bundle(path, pool, repeats=1, fps=FPS) for _ in range(runs)]


def _span(values: list[float], fmt: str = ".2f") -> str:
    return f"{np.median(values):{fmt}} ({min(values):{fmt}}-{max(values):{fmt}})"


def _bench_row(what: str, results: list, before: str) -> list[str]:
    """A goals-table row for ``tactile-force bench`` runs of one bundle: PASS count, verdicts and
    the bundle's bare-graph p99 at the cadence (the floor no runtime around it can beat)."""
    verdicts = [r.verdict for r in results]
    floors = [r.cadence.bare_ms.p99 for r in results if r.cadence is not None and r.cadence.bare_ms is not None
              and r.cadence.bare_ms.p99 is not None]
    floor = f"; its graph alone: p99 {_span(floors, '.3f')} ms" if floors else ""
    return [f"`tactile-force bench` at 60 fps, {what}", "PASS", before,
            f"{verdicts.count('PASS')} of {len(verdicts)} runs{floor}", ", ".join(sorted(set(verdicts)))]


def goals_table(rds: list[Round], bench: dict[str, list]) -> str:
    def ratio(name: str, q: float, worst: bool = False) -> list[float]:
        return [r.ratio(name, q, worst) for r in rds]

    def cpu(name: str) -> list[float]:
        return [100 * r.phases[name].cpu_share for r in rds]

    def per_reading(many: str, one: str) -> list[float]:
        return [r.phases[many].cpu_per_reading_ms / r.phases[one].cpu_per_reading_ms for r in rds]

    h = f"{HAND} sensors"
    rows = []
    for goal, limit, before, after in (
            ("1 sensor: total p50 / reference p50", 1.0, ratio("1 sensor, before", 50), ratio("1 sensor, after", 50)),
            ("1 sensor: total p99 / reference p50", 1.6, ratio("1 sensor, before", 99), ratio("1 sensor, after", 99)),
            ("1 sensor: process CPU, % of one core", 10.0, cpu("1 sensor, before"), cpu("1 sensor, after")),
            (f"{h}: worst sensor's total p99 / reference p50", 2.5, ratio(f"{h}, before", 99, True),
             ratio(f"{h}, after", 99, True)),
            (f"{h}: process CPU, % of one core", 50.0, cpu(f"{h}, before"), cpu(f"{h}, after")),
            (f"{h}: CPU per reading / one sensor's", 0.8, per_reading(f"{h}, before", "1 sensor, before"),
             per_reading(f"{h}, after", "1 sensor, after"))):
        met = sum(v <= limit for v in after)
        rows.append([goal, f"<= {limit:g}", _span(before), _span(after), f"{met} of {len(after)} rounds"])
    befores = {"default bundle": "0 of 5 runs (the fast fp32 RGBmod, default_bundle.md)",
               "int8 RGBmod": "0 of 5 runs (default_bundle.md)"}
    for what, results in bench.items():
        if results:
            rows.append(_bench_row(what, results, befores.get(what, "-")))
    return markdown_table(["goal", "limit", "before (warm-ups off)", "after (the default: warm-ups where they pay)",
                           "met"], rows)


#: The goals for one sensor at the cadence: ms the runtime may add to the bare call, per percentile.
ADDED_GOALS = {50: 0.15, 99: 0.25}


def floor_table(rds: list[Round]) -> str:
    """Ms added to the reference's percentile at the cadence, per round: by the floor (the one
    downscale, then the bare call) and by the runtime (one sensor, warm-ups off and the default),
    against :data:`ADDED_GOALS`."""
    def added(q: float, times: Callable[[Round], np.ndarray]) -> list[float]:
        return [float(np.percentile(times(r), q) - np.percentile(r.ref, q)) for r in rds]

    rows = []
    for q, goal in ADDED_GOALS.items():
        floor = added(q, lambda r: r.floor)
        cells = [f"p{q}", f"<= {goal:g}", _span(floor, "+.3f"), f"{sum(v <= goal for v in floor)} of {len(floor)}"]
        for name in ("1 sensor, before", "1 sensor, after"):
            cells.append(_span(added(q, lambda r, name=name: np.concatenate(r.phases[name].totals)), "+.3f"))
        rows.append(cells)
    return markdown_table(["percentile", "goal: ms added to the reference", "floor: one downscale + the bare call",
                           "floor within the goal (rounds)", "runtime, warm-ups off", "runtime, the default"], rows)


def stages_table(rds: list[Round]) -> str:
    rows = []
    for name in ("back to back", "1 sensor, before", "1 sensor, forced on", "1 sensor, after"):
        ph = [r.phases[name] for r in rds]
        cells = [float(np.median([np.percentile(p.stages[s], 50) for p in ph])) for s in STAGES]
        rows.append([name, *cells, float(np.median([p.cpu_per_reading_ms for p in ph])),
                     sum(p.prewarms for p in ph), sum(p.overran for p in ph)])
    rows.append(["reference (bare session)", "-", float(np.median([np.median(r.ref) for r in rds])), "-", "-", "-",
                 "-", "-"])
    return markdown_table(["one sensor", *(f"{s} p50 ms" for s in STAGES), "CPU ms / reading", "warm-ups",
                           "waited for one"], rows)


def phases_table(rds: list[Round]) -> str:
    rows = []
    for name in ("back to back", *PHASES):
        ph = [r.phases[name] for r in rds]
        states = sorted({p.state.split(" (")[0] for p in ph})
        rows.append([name, _span([p.p(50) for p in ph], ".3f"), _span([p.p(99) for p in ph], ".3f"),
                     _span([p.p(99, True) for p in ph], ".3f"), _span([100 * p.cpu_share for p in ph], ".1f"),
                     sum(p.readings for p in ph), " / ".join(states)])
    rows.append(["reference (bare session)", _span([float(np.median(r.ref)) for r in rds], ".3f"),
                 _span([float(np.percentile(r.ref, 99)) for r in rds], ".3f"), "-", "-", sum(len(r.ref) for r in rds),
                 "-"])
    rows.append(["floor: one downscale + the bare call", _span([float(np.median(r.floor)) for r in rds], ".3f"),
                 _span([float(np.percentile(r.floor, 99)) for r in rds], ".3f"), "-", "-",
                 sum(len(r.floor) for r in rds), "-"])
    return markdown_table(["phase", "total p50 ms", "total p99 ms", "worst sensor p99 ms", "process CPU %",
                           "readings", "warm-ups (RuntimeStats.prewarm)"], rows)


def run(args, argv) -> int:
    rounds, n = (1, 120) if args.quick else (args.rounds, 600)
    window = CpuWindow()
    rds, floor_path = measure(rounds, n)
    from tactile_force.edge.scene import shipped_bundles

    runs = 2 if args.quick else args.bench_runs
    int8 = shipped_bundles().get("rgbmod_int8")
    bench = {"default bundle": bench_passes(runs), "int8 RGBmod": bench_passes(runs, int8) if int8 else []}
    state = window.stop()
    from tactile_force.edge.files.atomic import staged_file
    from tactile_force.edge.typed_json import to_json

    summary = [{"reference_ms": np.percentile(r.ref, [50, 99]).tolist(),
                "floor_ms": np.percentile(r.floor, [50, 99]).tolist(),
                **{name: {"total_ms": [p.p(50), p.p(99), p.p(99, True)], "cpu_share": p.cpu_share,
                          "cpu_per_reading_ms": p.cpu_per_reading_ms, "prewarms": p.prewarms, "overran": p.overran,
                          "workers": p.workers,
                          "prewarm_state": p.state,
                          "stages_p50_ms": {k: float(np.percentile(v, 50)) for k, v in p.stages.items()}}
                   for name, p in r.phases.items()}} for r in rds]
    with staged_file(Path(args.out) / "cadence.json") as tmp:  # the measured figures, before any rendering
        tmp.write_text(json.dumps({"rounds": summary, "bench_verdicts": [r.verdict for r in bench["default bundle"]],
                                   "bench": {k: [to_json(r) for r in v] for k, v in bench.items()}}, indent=1) + "\n")
    notes = (f"{rounds} rounds of {n} frames per sensor and phase at {FPS:g} fps; per cell the median over rounds "
             f"(min-max). Before: the same runtime with `RuntimeOptions(prewarm=False)`; forced on: `prewarm=True`; "
             f"after: the default `prewarm='auto'` (the runtime tries warm-ups with and without and keeps them only "
             f"where they pay), counted from its decision on. The {HAND}-sensor phases ran a step's per-sensor work on "
             f"{rds[0].phases[f'{HAND} sensors, after'].workers} threads (`RuntimeOptions.workers` auto). "
             f"While measuring: {state.line()}.")
    text = header("Latency at the sensor's cadence", command_line(argv), describe_machine(), notes)
    text += "\n## Goals\n\n" + goals_table(rds, bench) + "\n"
    text += ("\n## What the runtime adds at the cadence, against its floor (one sensor)\n\n"
             "Ms added to the reference (the bare call at the same cadence) at each percentile, per round. The floor: "
             f"each frame's one downscale (the gate's reduction, {floor_path}; the image the network reads) and then "
             "the bare call on it, in the same process at the same cadence: what any runtime that reads a sensor's "
             "frame adds at the least. A goal below the floor cannot be met by removing the runtime's own work.\n\n"
             + floor_table(rds) + "\n")
    text += "\n## Every phase\n\n" + phases_table(rds) + "\n"
    text += "\n## Where the cold time goes (one sensor, per stage)\n\n" + stages_table(rds) + "\n"
    page = Path(args.out) / "cadence.md"
    old = page.read_text() if page.exists() else ""
    keep = old[old.index(MARK):] if MARK in old else MARK + "\n"  # the hand-kept findings
    with staged_file(page) as tmp:
        tmp.write_text(text + "\n" + keep)
    print(f"wrote {page}")
    return 0


#: Everything below this line in cadence.md is kept when the page is made again.
MARK = "<!-- hand-kept below: findings -->"
