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

The result is a :class:`BenchReport`, written as ``report.json`` (a stable contract, see
docs/bench.md), ``report.md`` and ``pareto.png`` (error against p99 latency, the budget line).
"""

from __future__ import annotations

import json
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

from tactile_force.edge.runtime.replay import replay_readings
from tactile_force.edge.typed_json import check

from .harness.budget import Attempt
from .harness.frames import contact_frames
from .harness.machine import Machine, MachineState

SCHEMA = "tactile-force-bench/1"
REPORT_JSON, REPORT_MD, PLOT_PNG = "report.json", "report.md", "pareto.png"
#: The stages a reading's latency carries, in report order (``depth`` only for depth variants).
STAGES = ("source", "gate", "depth", "inference", "glue", "total")
#: Readings not counted before each measurement (back to back and at the cadence).
WARMUP = 30


# ----------------------------------------------------------------------------- the contract
@dataclass
class Timing:
    """Percentiles of one stage in ms over ``n`` frames (None: not measured, e.g. depth of RGBmod)."""

    p50: float | None
    p90: float | None
    p99: float | None
    mean: float | None
    n: int


@dataclass
class Cadence:
    """A bundle measured with frames arriving at ``fps`` per second (each frame due at
    t0 + i / fps, the source sleeping until it is): ``total_ms`` as :attr:`BundleResult.total_ms`
    (frame arrival -> reading, over the frames read), ``cpu_share`` the process CPU time over
    the wall time meanwhile (0.05 = 5 % of one core; None: not measured), ``missed`` frames the
    runtime was late for (skipped, as a camera's newest-frame grabber skips them; no reading
    measured for them), ``bare_ms`` the bundle's graph alone in a bare onnxruntime session,
    one call per 1/fps tick (:func:`benchmarks.harness.latency.bare_at_cadence`): the floor no
    runtime around this network can beat at this cadence on this host (None: not measured)."""

    fps: float = field(metadata=check(gt=0))
    total_ms: Timing
    cpu_share: float | None
    missed: int = 0
    bare_ms: Timing | None = None


@dataclass
class BinError:
    """RE (dimensionless) and MAE (N), mean and std (ddof=0), over ``n`` CNN readings."""

    n: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float
    mae_std: float


@dataclass
class BenchError:
    """Error vs truth of a bundle on labelled data, measured through the runtime: overall
    figures over the ``n`` readings where the CNN gave a force and truth > 0 N, per 1 N bin
    of the true force (``"3-4"``: 3 <= f < 4 N), the labelled data and background used,
    the frames with truth and how many with truth >= 1 N got no force (``missed``)."""

    n: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float
    mae_std: float
    per_bin: dict[str, BinError]
    data: str
    background: str | None
    frames_with_truth: int
    missed: int


@dataclass
class BundleResult:
    """One bundle's row: where it is, what it is, its latency through ``ForceRuntime`` back to
    back (``total_ms``: frame arrival -> reading, what a reading's total_ms shows; ``stages_ms``:
    source, gate, depth, inference, glue) and at the sensor's cadence (``cadence``; None when
    not measured, e.g. by ``study`` or in a report from before it was measured), its error on
    labelled data (None without ``--data``), the error its manifest records (``manifest_re``,
    on the data it was made with), and its verdict against the budget, judged on the total
    p99 at the cadence (back to back without one): PASS, OVER_BUDGET, MACHINE_BUSY,
    TOO_FEW_READINGS, or NO_READINGS (most bench frames gave no force, e.g. the bundle fails on
    them: ``note`` says why). ``attempts`` carry the judged p99.
    ``precision`` is what the graph holds, as ``bundle verify`` reads it
    (:func:`tactile_force.edge.bundle.graph_facts.graph_precision`), not the manifest's word; ``note``
    says when the manifest claims another."""

    path: str
    name: str
    variant: str
    precision: str
    total_ms: Timing
    stages_ms: dict[str, Timing]
    error: BenchError | None
    manifest_re: float | None
    verdict: str
    attempts: list[Attempt] = field(default_factory=list)
    note: str = ""
    cadence: Cadence | None = None

    @property
    def judged_ms(self) -> Timing:
        """The total the verdict is judged on: at the cadence when measured, else back to back."""
        return self.cadence.total_ms if self.cadence is not None else self.total_ms


@dataclass
class BenchReport:
    """What ``tactile-force bench`` measured (``report.json``; docs/bench.md).

    verdict: PASS when every bundle's judged total p99 (at the cadence when measured) is
    within ``budget_ms``; else as :func:`overall_verdict`. ``frames``: readings measured back
    to back per bundle (at the cadence: each bundle's ``cadence.total_ms.n`` and its
    ``missed``)."""

    schema: str
    machine: Machine
    budget_ms: float
    threads: int
    frames: int
    verdict: str
    bundles: list[BundleResult]
    command: str = ""

    def to_json(self) -> dict:
        """Plain JSON values (NaN written as null)."""
        from tactile_force.edge.typed_json import to_json

        return to_json(self)

    @classmethod
    def from_json(cls, raw: object) -> BenchReport:
        """Parse and validate a ``report.json`` value; a wrong field raises
        :class:`tactile_force.edge.typed_json.TypedJsonError` naming its path."""
        from tactile_force.edge.typed_json import from_json

        return from_json(cls, raw, "report.json")

    @property
    def passed(self) -> bool:
        return self.verdict == "PASS"


def _f(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def _timing(p) -> Timing:
    return Timing(_f(p.p50), _f(p.p90), _f(p.p99), _f(p.mean), int(p.n))


def overall_verdict(verdicts: Sequence[str]) -> str:
    """PASS when all pass; else OVER_BUDGET when any is over budget; else NO_READINGS when a
    bundle gave no force on the bench frames; else TOO_FEW_READINGS when a bundle's p99 rests
    on too few readings; else MACHINE_BUSY."""
    if verdicts and all(v == "PASS" for v in verdicts):
        return "PASS"
    for v in ("OVER_BUDGET", "NO_READINGS", "TOO_FEW_READINGS"):
        if v in verdicts:
            return v
    return "MACHINE_BUSY"


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
    return BenchReport(SCHEMA, machine, float(budget_ms), int(threads), int(frames),
                       overall_verdict([r.verdict for r in results]), results, command)


# ----------------------------------------------------------------------------- output
VERDICT_TEXT = {"PASS": "PASS", "OVER_BUDGET": "over budget", "MACHINE_BUSY": "machine busy (no verdict)",
                "NO_READINGS": "no force on the bench frames (no verdict)",
                "TOO_FEW_READINGS": "too few readings for a p99 (no verdict)"}


def _ms(v: float | None) -> str:
    return "-" if v is None else f"{v:.3f}"


def cadence_label(report: BenchReport) -> str | None:
    """``"60 fps"`` when the bundles were measured at one cadence, ``"cadence"`` at several,
    None when none was (back to back only)."""
    fps = sorted({b.cadence.fps for b in report.bundles if b.cadence is not None})
    if not fps:
        return None
    return f"{fps[0]:g} fps" if len(fps) == 1 else "cadence"


def _share(v: float | None) -> str:
    return "-" if v is None else f"{100 * v:.1f} %"


def table_rows(report: BenchReport) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the results table (one row per bundle): the stages and total back to
    back (b2b), the total and process CPU at the cadence when measured."""
    at = cadence_label(report)
    head = ["bundle", "variant", "precision", "gate p50", "depth p50", "inference p50", "b2b total p50",
            "b2b total p99"]
    if at is not None:
        head += [f"{at} total p50", f"{at} total p99", f"{at} CPU", f"{at} bare graph p99"]
    head += ["RE (here)", "MAE N (here)", "RE (manifest)", "verdict"]
    rows = []
    for b in report.bundles:
        st = b.stages_ms
        e = b.error
        row = [b.name, b.variant, b.precision, _ms(st["gate"].p50 if "gate" in st else None),
               _ms(st["depth"].p50 if "depth" in st else None),
               _ms(st["inference"].p50 if "inference" in st else None), _ms(b.total_ms.p50), _ms(b.total_ms.p99)]
        if at is not None:
            c = b.cadence
            row += ["-", "-", "-", "-"] if c is None else [
                _ms(c.total_ms.p50), _ms(c.total_ms.p99), _share(c.cpu_share),
                _ms(c.bare_ms.p99 if c.bare_ms is not None else None)]
        row += ["-" if e is None or e.re_mean is None else f"{e.re_mean:.3f}",
                "-" if e is None else f"{e.mae_mean:.3f}", "-" if b.manifest_re is None else f"{b.manifest_re:.3f}",
                VERDICT_TEXT.get(b.verdict, b.verdict)]
        rows.append(row)
    return head, rows


def _measured_how(report: BenchReport) -> str:
    """What the table's columns are, in one sentence (text table and report.md)."""
    at = cadence_label(report)
    ns = sorted({b.cadence.total_ms.n for b in report.bundles if b.cadence is not None})
    b2b = (f"latency in ms through ForceRuntime, frames in contact, {report.threads} thread(s): stages and b2b "
           f"total with frames back to back ({report.frames} frames)")
    if at is None:
        return b2b + f"; budget: total p99 <= {report.budget_ms:g} ms"
    return (b2b + f"; {at}: frames arriving at the sensor's cadence, the source sleeping until each is due "
            f"({'/'.join(str(n) for n in ns)} readings), CPU = process CPU time / wall time meanwhile (of one core), "
            f"bare graph = the bundle's graph alone in a bare onnxruntime session at the same cadence (the floor); "
            f"budget: total p99 at {at} <= {report.budget_ms:g} ms")


def _missed_lines(report: BenchReport) -> list[str]:
    """What the table alone does not say: frames skipped at the cadence, and bundles whose
    graph alone misses the budget at the cadence (no runtime around it can meet it here)."""
    out = [f"{b.name}: {b.cadence.missed} frame(s) skipped at {b.cadence.fps:g} fps (the runtime was late for them; "
           "no reading measured for them)" for b in report.bundles if b.cadence is not None and b.cadence.missed]
    for b in report.bundles:
        c = b.cadence
        if b.verdict != "PASS" and c is not None and c.bare_ms is not None and c.bare_ms.p99 is not None \
                and c.bare_ms.p99 > report.budget_ms:
            out.append(f"{b.name}: its graph alone, in a bare onnxruntime session at {c.fps:g} fps, takes p99 "
                       f"{c.bare_ms.p99:.3f} ms > the {report.budget_ms:g} ms budget: no runtime around a network of "
                       "this size holds the budget on this host; try a smaller one (edge/models/fast, "
                       "tactile-force compress)")
    return out


def text_table(report: BenchReport) -> str:
    """The results as aligned plain text (what the CLI prints), machine state per bundle after it."""
    head, rows = table_rows(report)
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(head)]
    out = ["  ".join(h.ljust(w) for h, w in zip(head, widths))]
    out += ["  ".join(c.ljust(w) for c, w in zip(r, widths)) for r in rows]
    out.append(_measured_how(report))
    out += _missed_lines(report)
    for b in report.bundles:
        for i, a in enumerate(b.attempts, 1):
            out.append(f"{b.name} attempt {i}: total p99 {_judged(b)}{_ms(a.total_p99_ms)} ms; {a.machine.line()}")
        if b.verdict == "TOO_FEW_READINGS":
            out.append(f"{b.name}: {b.note}")
    out.append(f"verdict: {VERDICT_TEXT.get(report.verdict, report.verdict)}")
    return "\n".join(out)


def _judged(b: BundleResult) -> str:
    return f"at {b.cadence.fps:g} fps " if b.cadence is not None else ""


def markdown(report: BenchReport) -> str:
    """report.md: command, commit, machine, the table, per-bin error, machine state per attempt."""
    from .harness.paths import source_commit

    head, rows = table_rows(report)
    m = report.machine
    how = _measured_how(report)
    lines = ["# tactile-force bench", "", f"Command: `{report.command}`" if report.command else "",
             f"Commit: {source_commit()}", f"Machine: {m.line()}.",
             f"At start: {m.background_load}.", "",
             f"{how[0].upper()}{how[1:]}. In-memory sources; total = frame arrival -> reading. "
             f"Verdict: **{VERDICT_TEXT.get(report.verdict, report.verdict)}**.",
             *([""] + [f"- {line}" for line in _missed_lines(report)] if _missed_lines(report) else []), "",
             "| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    for b in report.bundles:
        lines += ["", f"## {b.name}", "", f"Path: `{b.path}`." + (f" Note: {b.note}." if b.note else "")]
        for i, a in enumerate(b.attempts, 1):
            lines.append(f"- attempt {i}: total p99 {_judged(b)}{_ms(a.total_p99_ms)} ms; {a.machine.line()}")
        if b.error is not None:
            e = b.error
            lines += ["", f"Error on `{e.data}` (background `{e.background}`): {e.n} CNN readings of "
                      f"{e.frames_with_truth} frames with truth; {e.missed} with truth >= 1 N got no force.", "",
                      "| force bin (N) | n | RE | MAE (N) |", "|---|---|---|---|"]
            lines += [f"| {k} | {s.n} | {'-' if s.re_mean is None else f'{s.re_mean:.3f}'} | {s.mae_mean:.3f} |"
                      for k, s in e.per_bin.items()]
    return "\n".join(lines).replace("\n\n\n", "\n\n") + "\n"


def plot(report: BenchReport, path: Path) -> Path:
    """Error against the judged p99 latency (at the cadence when measured), one point per
    bundle, its back-to-back p99 as a grey mark joined to it, the budget line (OpenCV)."""
    from tactile_force.edge.report.plots import ParetoPoint, error_vs_latency

    pts = []
    for b in report.bundles:
        measured = b.error is not None and b.error.re_mean is not None
        err = b.error.re_mean if measured and b.error is not None else b.manifest_re
        p99 = b.judged_ms.p99
        pts.append(ParetoPoint(b.name, p99 if p99 is not None else math.nan, err, measured,
                               b.total_ms.p99 if b.cadence is not None else None))
    at = cadence_label(report)
    title = f"{report.machine.cpu}, {report.threads} thread(s)" + (f", p99 at {at}" if at else "")
    return error_vs_latency(pts, report.budget_ms, path, title=title, also="back to back")


def write_json(path: Path, obj: object) -> Path:
    """``obj`` as indented JSON at ``path``, replaced atomically (a reader never sees half a file)."""
    from tactile_force.edge.files.atomic import staged_file

    with staged_file(path) as tmp:
        tmp.write_text(json.dumps(obj, indent=2) + "\n")
    return path


def write_report(report: BenchReport, out: Path) -> list[Path]:
    """Write report.json, report.md and pareto.png into the folder ``out`` (made if missing;
    the CLI passes a hidden staging folder that becomes ``--out`` when all three are written)."""
    out.mkdir(parents=True, exist_ok=True)
    js = write_json(out / REPORT_JSON, report.to_json())
    md = out / REPORT_MD
    md.write_text(markdown(report))
    return [js, md, plot(report, out / PLOT_PNG)]


def read_report(path: str | os.PathLike) -> BenchReport:
    """Read a report.json back into a :class:`BenchReport`."""
    return BenchReport.from_json(json.loads(Path(path).read_text()))


__all__ = ["Attempt", "BenchError", "BenchReport", "BinError", "BundleResult", "Cadence", "Machine", "MachineState",
           "Timing", "bench_bundle", "contact_frames", "markdown", "overall_verdict", "read_report", "replay_error",
           "replay_readings", "run_bench", "text_table", "write_report"]
