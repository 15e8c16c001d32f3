"""``tactile-force study``: which precision to ship for THIS host - a quantization study of the
user's fp32 bundle (or checkpoint) on the user's labelled data.

Every configuration is made with :func:`tactile_force.export.quantize_bundle` (one
implementation of quantization, its calibration reader and methods): fp32, fp16, int8
dynamic, and int8 static x calibration method (:data:`~tactile_force.export.quantize.METHODS`)
x per-channel / per-tensor x nodes kept float; a per-node sensitivity ranking tells which
single node, kept float, buys back the most int8 error. Each configuration is measured
through the runtime on this host:

- error vs truth: the labelled folder replayed through ``ForceRuntime`` exactly as ``tactile-force
  run`` / ``bench --data`` do (:func:`tactile_force.edge.runtime.replay.replay_readings`), RE and
  MAE as ``run`` reports them; error vs fp32: the same readings against the fp32 bundle's, frame
  by frame;
- latency: ``tactile-force bench``'s measurement (:func:`tactile_force.benchmarks.bench.bench_bundle`,
  virtual DIGIT frames in contact from memory, one verdict attempt), back to back only (no run
  at the sensor's cadence: the configurations are ranked against each other).

Writes study.json (:class:`StudyReport`), study.md, pareto.png (error vs p99, the budget line)
and the Pareto-front bundles under ``out/bundles/``; the recommended configuration is the most
accurate one whose p99 is within the budget.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from tactile_force.edge.errors import TactileForceError

from .quantize import METHODS
from .study_report import (
    SCHEMA,
    ConfigError,
    Configuration,
    Latency,
    Sensitivity,
    Settings,
    StudyReport,
    _row_text,
    markdown,
    read_study,
    write_study,
)

if TYPE_CHECKING:
    from .calibration import CalibrationData

#: labelled frames a study needs at least (int8 static calibration needs as many; fewer give no error figure)
MIN_STUDY_FRAMES = 10


class StudyError(TactileForceError, ValueError):
    """A study input is unusable (exit 2); the message names it."""


@dataclass
class StudyOptions:
    """What to study. quick: a small grid (fp32, int8 dynamic, int8 static minmax and percentile
    per channel, 3 sensitivity nodes); max_configs: at most this many configurations besides
    fp32 (None: all); sensitivity_nodes: nodes ranked (None: every Conv); frames: latency
    readings per configuration; budget_ms: the p99 budget for the recommendation."""

    budget_ms: float = 1.0
    threads: int = 1
    frames: int = 500
    quick: bool = False
    max_configs: int | None = None
    sensitivity_nodes: int | None = None
    max_calibration_frames: int = 200
    show_progress: bool = True
    keep_bundles: str = "pareto"  # "pareto" | "all"

    def __post_init__(self) -> None:
        if self.keep_bundles not in ("pareto", "all"):
            raise StudyError(f"keep_bundles={self.keep_bundles!r}; expected 'pareto' or 'all'")


def _f(v: float | None) -> float | None:
    return None if v is None or not math.isfinite(v) else float(v)


def slug(name: str) -> str:
    """A folder name for a configuration name."""
    return re.sub(r"[^A-Za-z0-9.+-]+", "_", name).strip("_")


# ----------------------------------------------------------------------------- the grid
def conv_nodes(onnx_path: Path) -> list[tuple[str, str]]:
    """(name, op) of the graph's named Conv / Gemm nodes, in graph order."""
    import onnx

    m = onnx.load(str(onnx_path), load_external_data=False)
    return [(n.name, n.op_type) for n in m.graph.node if n.op_type in ("Conv", "Gemm") and n.name]


def grid(first_conv: str | None, quick: bool = False) -> list[tuple[str, Settings]]:
    """(name, settings) of every configuration besides fp32, in study order."""
    out: list[tuple[str, Settings]] = []
    out.append(("int8-dynamic", Settings("int8-dynamic", per_channel=True)))
    if not quick:
        out.append(("fp16", Settings("fp16")))
    methods = ("minmax", "percentile") if quick else METHODS
    keeps: list[list[str]] = [[]] + ([[first_conv]] if first_conv and not quick else [])
    for method in methods:
        for per_channel in ((True,) if quick else (True, False)):
            for keep in keeps:
                name = f"int8-static {method} {'per-channel' if per_channel else 'per-tensor'}"
                if keep:
                    name += f" +{keep[0]} float"
                out.append((name, Settings("int8-static", method, per_channel, list(keep))))
    return out


# ----------------------------------------------------------------------------- measuring
def _errors(readings: list, fp32_by_frame: dict[int, float] | None, data: Path, background: Path | None
            ) -> ConfigError | None:
    from tactile_force.benchmarks.bench import replay_error
    from tactile_force.edge.data.metrics import cnn_readings

    e = replay_error(Path("."), data, background, readings=readings)
    if e is None:
        return None
    vs: list[float] = []
    if fp32_by_frame is not None:
        for r in cnn_readings(readings):
            ref = fp32_by_frame.get(r.frame_index)
            if ref is not None:
                vs.append(abs(r.force_n - ref))
    return ConfigError(e.n, e.re_mean, e.re_std, e.mae_mean, e.mae_std,
                       float(np.mean(vs)) if vs else None, float(np.max(vs)) if vs else None, len(vs))


def _by_frame(readings: list) -> dict[int, float]:
    from tactile_force.edge.data.metrics import cnn_readings

    return {r.frame_index: float(r.force_n) for r in cnn_readings(readings)}


def _latency(path: Path, pool, o: StudyOptions) -> Latency:
    from tactile_force.benchmarks.bench import bench_bundle

    r = bench_bundle(path, pool, frames=o.frames, threads=o.threads, budget_ms=o.budget_ms, repeats=1,
                     warmup=min(30, max(3, o.frames // 10)))
    inf = r.stages_ms.get("inference")
    return Latency(r.total_ms.p50, r.total_ms.p99, inf.p50 if inf else None, r.total_ms.n)


def _predict(path: Path, calib) -> np.ndarray:
    """The bundle's forces (N) on loaded frames (direct, for the sensitivity ranking)."""
    from tactile_force.edge.model.onnx_model import OnnxForceModel

    model = OnnxForceModel(path, threads=1)
    try:
        out = [np.asarray(model.predict(b.get("rgb"), b.get("depth")), np.float64).reshape(-1)
               for b in calib.batches(1)]
    finally:
        close = getattr(model, "close", None)
        if close is not None:
            close()
    return np.concatenate(out) if out else np.zeros(0)


def prepare_source(source: Path, work: Path, variant: str | None = None, width: float | None = None,
                   input_scale: float | None = None, parity_data: Path | None = None) -> Path:
    """The fp32 bundle to study: ``source`` itself when it is a bundle folder (must be fp32),
    else the checkpoint exported (verified) into ``work/fp32``."""
    from tactile_force.edge.bundle.store import load_bundle

    if source.is_dir():
        if not (source / "model.json").is_file():
            raise StudyError(f"{source}: not a bundle folder (no model.json) and not a checkpoint file")
        b = load_bundle(source)
        if str(b.manifest.precision) != "fp32":
            raise StudyError(f"{source}: is a {b.manifest.precision} bundle; the study starts from the fp32 bundle "
                             "(tactile-force export) or a checkpoint")
        return source
    if not source.is_file():
        raise StudyError(f"{source}: not found (expected an fp32 bundle folder or a checkpoint .pth / .pth.tar)")
    from .onnx_export import ExportOptions, export_bundle

    dest = work / "fp32"
    export_bundle(source, dest, ExportOptions(variant=variant, width=width, input_scale=input_scale,
                                              parity_data=parity_data, overwrite=True, name="study-fp32",
                                              trained_on=f"checkpoint {source.name}"))
    return dest


def run_study(fp32: Path, data: Path, out: Path, options: StudyOptions | None = None,
              calibration: str | os.PathLike | CalibrationData | None = None, background: Path | None = None,
              command: str = "", pool=None, log: Callable[[str], None] | None = None,
              publish_as: Path | None = None) -> StudyReport:
    """Quantize ``fp32`` every way in the grid, measure each configuration, write the study.

    Parameters
    ----------
    fp32 : Path
        The fp32 bundle (:func:`prepare_source` makes one from a checkpoint).
    data : Path
        Labelled frames in the authors' layout (images/N.png + forces/force_N.txt): the error.
    out : Path
        Output folder: study.json, study.md, pareto.png, bundles/<configuration>/.
    options : StudyOptions
        Grid size, budget, threads, latency frames.
    calibration : Path or CalibrationData, optional
        int8 static calibration frames (default: ``data`` itself, noted as the same frames).
    background : Path, optional
        No-contact image of ``data``'s sensor (else learnt from the first frames, as ``run`` does).
    command : str
        The command line, recorded.
    pool : FramePool, optional
        Latency frames (default :func:`tactile_force.benchmarks.bench.contact_frames`).
    publish_as : Path, optional
        Where ``out`` will be moved when the study ends (a staging folder is written): the
        report records bundle paths under it.

    Returns
    -------
    StudyReport
        Also written to ``out/study.json``.
    """
    from tactile_force.benchmarks.bench import contact_frames
    from tactile_force.benchmarks.harness.machine import describe_machine
    from tactile_force.edge.bundle.store import load_bundle
    from tactile_force.edge.report.plots import ParetoPoint, pareto_front
    from tactile_force.edge.report.progress import progress
    from tactile_force.edge.runtime.replay import replay_readings

    from .calibration import CalibrationData
    from .quantize import QuantizeOptions, quantize_bundle

    o = options or StudyOptions()
    say = log or (lambda s: None)
    t0 = time.perf_counter()
    fp32 = Path(fp32)
    manifest = load_bundle(fp32).manifest
    variant = str(manifest.variant)
    if not Path(data).is_dir():
        raise StudyError(f"--data {data}: folder not found (expected the authors' layout: images/N.png + "
                         "forces/force_N.txt)")
    if isinstance(calibration, CalibrationData):
        calib = calibration.subset(o.max_calibration_frames)
    else:
        calib = CalibrationData.from_path(calibration or data, variant, limit=o.max_calibration_frames,
                                          min_frames=MIN_STUDY_FRAMES)
    same = calibration is None or (not isinstance(calibration, CalibrationData)
                                   and Path(calibration).resolve() == Path(data).resolve())
    pool = pool if pool is not None else contact_frames()
    work = out / "bundles"
    work.mkdir(parents=True, exist_ok=True)
    nodes = conv_nodes(fp32 / manifest.onnx_file)
    convs = [n for n, op in nodes if op == "Conv"]
    configs = grid(convs[0] if convs else None, o.quick)
    if o.max_configs is not None:
        configs = configs[:max(0, o.max_configs)]

    fp32_readings = replay_readings(fp32, data, background, o.threads)
    labelled = sum(1 for r in fp32_readings if getattr(r, "truth_n", None) is not None)
    if labelled < MIN_STUDY_FRAMES:
        raise StudyError(f"--data {data}: {labelled} labelled frame(s); a study needs at least {MIN_STUDY_FRAMES} "
                         "(a few hundred covering the force range give a trustworthy error)")
    fp32_frames = _by_frame(fp32_readings)
    results = [Configuration("fp32", Settings("fp32"), _errors(fp32_readings, fp32_frames, data, background),
                             _latency(fp32, pool, o), bundle=str(fp32), note="the source")]
    paths: dict[str, Path] = {"fp32": fp32}
    say(f"fp32: {_row_text(results[0])}")

    def make(name: str, s: Settings) -> Path:
        dest = work / slug(name)
        qo = QuantizeOptions(mode=s.mode, method=s.method or "minmax",
                             per_channel=True if s.per_channel is None else s.per_channel,
                             keep_float=list(s.keep_float),
                             name=f"{manifest.name}-{slug(name)}", overwrite=True,
                             max_calibration_frames=o.max_calibration_frames)
        with contextlib.redirect_stdout(io.StringIO()):  # onnxruntime's calibrator prints progress chatter
            quantize_bundle(fp32, dest, qo, calibration=calib, eval_data=calib.subset(16))
        return dest

    for name, s in progress(configs, desc="study", enabled=o.show_progress):
        try:
            path = make(name, s)
        except TactileForceError as exc:  # e.g. a method that gives non-finite forces: recorded, not fatal
            results.append(Configuration(name, s, None, Latency(None, None, None, 0), note=f"not made: {exc}"))
            say(f"{name}: not made: {exc}")
            continue
        paths[name] = path
        readings = replay_readings(path, data, background, o.threads)
        results.append(Configuration(name, s, _errors(readings, fp32_frames, data, background),
                                     _latency(path, pool, o)))
        say(f"{name}: {_row_text(results[-1])}")

    # sensitivity: which single node kept float buys back the most of the base int8 error vs fp32
    sens: list[Sensitivity] = []
    base_name = "int8-static minmax per-channel"
    ranked = [n for n in nodes if n[1] == "Conv"]
    limit = o.sensitivity_nodes if o.sensitivity_nodes is not None else (3 if o.quick else None)
    if limit is not None:
        ranked = ranked[:limit]
    if base_name in paths and ranked:
        ref = _predict(fp32, calib)
        base = float(np.mean(np.abs(_predict(paths[base_name], calib) - ref)))
        tmp = work / ".sensitivity"
        for node, op in progress(ranked, desc="sensitivity", enabled=o.show_progress):
            qo = QuantizeOptions(mode="int8-static", method="minmax", per_channel=True, keep_float=[node],
                                 name=f"sensitivity-{node}", overwrite=True,
                                 max_calibration_frames=o.max_calibration_frames)
            try:
                with contextlib.redirect_stdout(io.StringIO()):
                    quantize_bundle(fp32, tmp, qo, calibration=calib, eval_data=calib.subset(4))
            except TactileForceError as exc:
                say(f"sensitivity {node}: not made: {exc}")
                continue
            mae = float(np.mean(np.abs(_predict(tmp, calib) - ref)))
            sens.append(Sensitivity(node, op, mae, (base - mae) / base if base > 0 else 0.0))
        shutil.rmtree(tmp, ignore_errors=True)
        sens.sort(key=lambda x: -x.bought_back)
        if sens and sens[0].bought_back > 0:
            best = sens[0].node
            name = f"int8-static minmax per-channel +{best} float (most sensitive node)"
            if not any(c.settings.mode == "int8-static" and c.settings.method == "minmax" and c.settings.per_channel
                       and c.settings.keep_float == [best] for c in results):
                s = Settings("int8-static", "minmax", True, [best])
                path = make(name, s)
                paths[name] = path
                readings = replay_readings(path, data, background, o.threads)
                results.append(Configuration(name, s, _errors(readings, fp32_frames, data, background),
                                             _latency(path, pool, o)))
                say(f"{name}: {_row_text(results[-1])}")

    # Pareto front, budget, recommendation, bundles kept
    pts = [ParetoPoint(c.name, c.latency_ms.p99 if c.latency_ms.p99 is not None else math.nan,
                       c.error.re_mean if c.error is not None else None) for c in results]
    for i in pareto_front(pts):
        results[i].pareto = True
    from tactile_force.benchmarks.harness.stats import too_few_for_p99

    few = too_few_for_p99(min((c.latency_ms.n for c in results), default=0))
    for c in results:
        c.within_budget = (few is None and c.latency_ms.p99 is not None and c.latency_ms.p99 <= o.budget_ms)
    fits = [(c.error.re_mean, i) for i, c in enumerate(results)
            if c.within_budget and c.error is not None and c.error.re_mean is not None]
    recommended = results[min(fits)[1]].name if fits else None
    def recorded(p: Path) -> str:
        """``p``'s path once ``out`` is published as ``publish_as``."""
        if publish_as is None:
            return str(p)
        try:
            return str(Path(publish_as) / Path(p).relative_to(out))
        except ValueError:
            return str(p)

    for c in results:
        p = paths.get(c.name)
        keep = c.pareto or c.name == recommended or o.keep_bundles == "all"
        if p is None:
            continue
        if p == fp32:
            c.bundle = recorded(p)
            continue
        if keep:
            c.bundle = recorded(p)
        else:
            shutil.rmtree(p, ignore_errors=True)
    m = describe_machine()
    report = StudyReport(
        schema=SCHEMA, source=recorded(fp32), variant=variant, data=str(data), calibration=calib.source,
        same_frames=same,
        budget_ms=float(o.budget_ms), threads=o.threads, frames=o.frames,
        machine={"cpu": m.cpu, "cores": m.cores, "ram_gib": _f(m.ram_gib), "os": m.os, "python": m.python,
                 "versions": m.versions, "background_load": m.background_load},
        configurations=results, sensitivity=sens, sensitivity_base=base_name if sens else None,
        recommended=recommended, seconds=round(time.perf_counter() - t0, 1), command=command, note=few or "")
    write_study(report, out)
    return report


__all__ = ["Configuration", "ConfigError", "Latency", "Sensitivity", "Settings", "StudyError", "StudyOptions",
           "StudyReport", "grid", "markdown", "prepare_source", "read_study", "run_study", "write_study"]
