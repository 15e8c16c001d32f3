"""CLI: ``tactile-force run``, ``tactile-force scene show FILE``, ``tactile-force demo``.

``run`` takes a scene file (``--scene``) or builds the same scene from flags (``--source``
...). Exit codes follow :mod:`tactile_force.edge.cli`: 0 success, 1 a check failed (every
sensor lost mid-run), 2 bad input (a scene or flag, a missing file, a run that produced no
reading).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
import threading
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np

from ..errors import CheckFailedError, SceneError, SourceError
from ..reading import Flags, ForceReading
from ..report.plots import nice_ticks  # noqa: F401 - re-exported (tests, older callers)
from .args import positive_float, positive_int

#: File name of the demo's force-over-time plot (README and docs name it too).
PLOT_NAME = "force_vs_time.png"


# -- scene show ---------------------------------------------------------------------------
def configure_scene(p: argparse.ArgumentParser) -> None:
    sub = p.add_subparsers(dest="action", required=True)
    show = sub.add_parser("show", help="print the stages the scene will run and make every check 'run' makes before "
                                       "it opens a device (opens no device, loads no model); exit 2, as 'run' would, "
                                       "when it would refuse the scene")
    show.add_argument("file", help="scene TOML file")
    show.add_argument("--force", action="store_true",
                      help="check as 'run --force' would (existing outputs may be replaced, never an input)")


def main_scene(args: argparse.Namespace) -> int:
    from ..scene import describe_scene, load_scene
    from ..scene.preflight import run_refusals

    scene = load_scene(args.file, check=False)
    print("\n".join(describe_scene(scene)))
    problems = run_refusals(scene, args.file, force=getattr(args, "force", False))
    for p in problems:
        print(f"error: {p}", file=sys.stderr)
    if problems:
        print(f"scene {scene.origin}: {len(problems)} problem(s); 'tactile-force run' would stop on them (exit 2)",
              file=sys.stderr)
        return 2
    return 0


# -- run ----------------------------------------------------------------------------------
def configure_run(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = (
        "Stream force readings from a scene file, or from one source given by flags:\n"
        "  tactile-force run --scene edge/scenes/replay_rgbmod.toml\n"
        "  tactile-force run --source REPLAY_DIR --bundle BUNDLE --background NO_CONTACT.png --out readings.csv\n"
        "--source: a replay folder, a video file, digit:SERIAL, gelsight_mini[:SERIAL], camera:DEVICE or virtual.\n"
        "Output paths are relative to the working directory. A replay with ground truth ends with RE and MAE.")
    p.add_argument("--scene", help="scene TOML file (see docs/runtime.md and edge/scenes/)")
    p.add_argument("--source", help="run without a scene file: the one sensor's source (see above)")
    p.add_argument("--bundle", default=None, help="with --source: model bundle folder (default: the embedded model)")
    p.add_argument("--background", help="with --source: no-contact image (or folder of them); "
                                        "else learnt from the first frames")
    p.add_argument("--fps", type=positive_float, help="with --source: camera rate, or pace a replay at this rate")
    p.add_argument("--name", default="sensor", help="with --source: the sensor's name in readings (default: sensor)")
    p.add_argument("--out", action="append", default=[], metavar="FILE",
                   help="with --source: also write readings to FILE.csv, FILE.jsonl or FILE.mcap (repeatable)")
    p.add_argument("--mcap-frames", action="store_true",
                   help="with --out FILE.mcap: also log each frame (JPEG) and its contact mask (PNG) there")
    p.add_argument("--ros2", metavar="TOPIC", help="with --source: publish readings on this ROS 2 topic")
    p.add_argument("--save-scene", metavar="FILE", help="write the scene that runs as a TOML file")
    p.add_argument("--max-frames", type=positive_int, default=None,
                   help="stop after this many readings (>= 1; default: scene / until sources end)")
    p.add_argument("--force", action="store_true",
                   help="replace --out / --save-scene files that exist (never an input)")
    p.add_argument("--depth-mapping", metavar="FILE",
                   help="with --source and a depth bundle (d, dmod, rgbmod+d) whose manifest records no mapping: "
                        "the colour->normal .npz (the paper MLP or a 'tactile-force calibrate-depth' result)")


def _summary_lines(stats, runtime) -> list[str]:
    lat = stats.latency_ms
    lines = [(f"readings {stats.readings}: processed {stats.processed}, CNN {stats.inferred}, "
              f"no_contact {stats.no_contact}, stale {stats.stale}, late {stats.late}, invalid {stats.invalid}, "
              f"source errors {stats.source_errors}")]
    lines.append("latency ms (p50 / p99): " + ", ".join(
        f"{k} {v['p50']:.2f}/{v['p99']:.2f}" for k, v in lat.items() if not math.isnan(v["p50"])))
    for s in runtime.sensors:
        st = s.source.stats
        lines.append(f"sensor {s.name}: frames {st.frames}, dropped {st.dropped}, corrupt {st.corrupt}"
                     + (f", ERROR {s.error}" if s.error else ""))
    return lines


def cnn_readings(readings: list[ForceReading]) -> list[ForceReading]:
    """Readings where the CNN gave a force and the frame has a truth > 0 N (what RE/MAE are over)."""
    skip = Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.STALE
    return [r for r in readings if not (r.flags & skip) and math.isfinite(r.force_n)
            and r.truth_n is not None and r.truth_n > 0]


def readings_error(readings: list[ForceReading]):
    """The error of a replay with truth, as ``run`` reports it: (ErrorReport over
    :func:`cnn_readings` or None when there is none, frames with truth, frames with truth
    >= 1 N that got no CNN reading). ``tactile-force bench --data`` reports the same figures."""
    from ..data.metrics import error_report

    with_truth = [r for r in readings if r.truth_n is not None and Flags.STALE not in r.flags]
    cnn = cnn_readings(readings)
    in_cnn = {id(r) for r in cnn}
    missed = sum(1 for r in with_truth if r.truth_n is not None and r.truth_n >= 1.0 and id(r) not in in_cnn)
    rep = error_report([r.force_n for r in cnn], [float(r.truth_n or 0.0) for r in cnn]) if cnn else None
    return rep, len(with_truth), missed


def truth_lines(readings: list[ForceReading]) -> list[str]:
    """RE and MAE (mean +- std) over the CNN readings with truth, overall and per 1 N bin,
    and how many frames with truth >= 1 N got no CNN reading; [] when no frame had truth."""
    rep, n_truth, missed = readings_error(readings)
    if not n_truth:
        return []
    lines = []
    if rep is not None:
        o = rep.overall
        lines.append(f"error vs truth over {o.n} CNN readings: RE {o.re_mean:.3f} +- {o.re_std:.3f}, "
                     f"MAE {o.mae_mean:.3f} +- {o.mae_std:.3f} N")
        for label, st in rep.per_bin.items():
            lines.append(f"  {label + ' N':>8}: RE {st.re_mean:.3f} +- {st.re_std:.3f}, "
                         f"MAE {st.mae_mean:.3f} +- {st.mae_std:.3f} N  (n={st.n})")
    else:
        lines.append(f"error vs truth: no CNN reading among the {n_truth} frames with truth")
    if missed:
        lines.append(f"{missed} frame(s) with truth >= 1 N got no force estimate (no_contact or invalid_input)")
    return lines


class LearningStatus:
    """A reading sink that says when a sensor's background has been learnt:
    ``left: background learnt from 5 frames`` on ``stream`` (the live status line shows
    ``learning background`` meanwhile, from the readings' detail)."""

    def __init__(self, stream: TextIO | None = None) -> None:
        self.stream = stream or sys.stderr
        self._learning: dict[str, int] = {}

    def write(self, r: ForceReading) -> None:
        if r.detail == "learning background":
            self._learning[r.sensor] = self._learning.get(r.sensor, 0) + 1
        elif r.sensor in self._learning and Flags.STALE not in r.flags:
            self.stream.write(f"\n{r.sensor}: background learnt from {self._learning.pop(r.sensor)} frames\n")
            self.stream.flush()

    def close(self) -> None:
        for name, n in self._learning.items():
            self.stream.write(f"\n{name}: still learning the background after {n} frames when the run ended\n")
        self._learning.clear()


class SignalStop:
    """SIGTERM and SIGINT stop ``tactile-force run`` cleanly: the first one ends the run after
    the readings of the step in progress are written (every sensor is marked done, so
    :meth:`ForceRuntime.run` returns), then the outputs are closed as at a normal end (an MCAP
    log gets its summary and footer). A second signal stops at once (KeyboardInterrupt; the
    outputs are still closed). Installed only in the main thread; the old handlers come back
    on exit."""

    def __init__(self, runtime) -> None:
        self.runtime = runtime
        self.signal: signal.Signals | None = None
        self._old: dict[int, object] = {}

    def __enter__(self) -> SignalStop:
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGTERM, signal.SIGINT):
                self._old[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, old in self._old.items():
            signal.signal(sig, old)  # type: ignore[arg-type]
        self._old.clear()

    def _handle(self, signum: int, frame) -> None:
        if self.signal is not None:
            raise KeyboardInterrupt
        self.signal = signal.Signals(signum)

    def check(self) -> None:
        """Called after each reading: on a pending signal, mark every sensor done."""
        if self.signal is not None:
            for s in self.runtime.sensors:
                s.alive = False


def _run_scene(args: argparse.Namespace):
    """The validated Scene for ``run``'s flags (from --scene, or built from --source): every
    check of :func:`~tactile_force.edge.scene.preflight.run_refusals` (the ones ``scene show``
    makes) passed, else SceneError listing what it refuses."""
    from ..scene import load_scene, scene_from_flags
    from ..scene.preflight import run_refusals

    given = [f"--{k.replace('_', '-')}" for k in ("bundle", "background", "fps", "ros2", "depth_mapping")
             if getattr(args, k, None) is not None] + (["--out"] if args.out else []) \
        + (["--mcap-frames"] if getattr(args, "mcap_frames", False) else [])
    if args.scene and args.source:
        raise SceneError("give --scene FILE or --source SRC, not both")
    if args.scene:
        if given:
            raise SceneError(f"{', '.join(given)}: only with --source; a scene file sets these itself")
        scene = load_scene(args.scene, check=False)
        _refuse(run_refusals(scene, args.scene, force=getattr(args, "force", False)))
        return scene
    if not args.source:
        raise SceneError("give --scene FILE, or --source SRC [--bundle B] (see tactile-force run --help)")
    from ..files.guard import OutputKind, check_input, check_output

    for flag in ("source", "bundle", "background", "depth_mapping"):
        if getattr(args, flag, None) is not None:
            check_input(getattr(args, flag), f"--{flag.replace('_', '-')}")
    inputs = [(f"--{k.replace('_', '-')}", getattr(args, k, None)) for k in ("source", "bundle", "background",
                                                                             "depth_mapping")]
    for out in args.out:
        check_output(out, [(f, p) for f, p in inputs if p not in (None, "default")],
                     force=getattr(args, "force", False), kind=OutputKind.FILE)
    scene = scene_from_flags(args.source, bundle=args.bundle or "default", background=args.background,
                             outputs=args.out, ros2=args.ros2, name=args.name, fps=args.fps,
                             mcap_frames=getattr(args, "mcap_frames", False),
                             depth_mapping=getattr(args, "depth_mapping", None))
    if scene.sensors[0].kind.live:
        scene.outputs[0].live = True
    _check_depth_mapping(scene)
    _refuse(run_refusals(scene))
    return scene


def _refuse(problems: list[str]) -> None:
    """SceneError listing every problem (exit 2), when there is one."""
    if problems:
        raise SceneError("; ".join(problems))


def _check_depth_mapping(scene) -> None:
    """SceneError naming --depth-mapping when a depth bundle run from flags has no mapping
    (neither recorded in its manifest nor given)."""
    from ..bundle.store import load_bundle
    from ..errors import BundleError

    if scene.depth.mapping is not None:
        return
    for b in scene.bundles:
        try:
            m = load_bundle(b).manifest
        except BundleError:
            continue  # the runtime reports it
        if m.needs_depth and (m.depth is None or m.depth.mapping is None):
            variant = getattr(m.variant, "value", m.variant)
            raise SceneError(f"bundle {b}: a depth bundle ({variant}) whose manifest records no colour->normal "
                             "mapping; pass --depth-mapping FILE.npz (the paper MLP or a 'tactile-force "
                             "calibrate-depth' result), or use a scene file with [depth] mapping = FILE")


def main_run(args: argparse.Namespace) -> int:
    from ..scene import build_scene, save_scene

    scene = _run_scene(args)
    if args.save_scene:
        from ..files.guard import OutputKind, check_output
        from ..scene.preflight import scene_inputs

        inputs = [*scene_inputs(scene, args.scene), ("--source", args.source), ("--bundle", args.bundle),
                  ("--background", args.background), ("--depth-mapping", getattr(args, "depth_mapping", None))]
        check_output(args.save_scene, [(f, p) for f, p in inputs if p not in (None, "default")],
                     force=getattr(args, "force", False), kind=OutputKind.FILE, flag="--save-scene")
        print(f"wrote scene {save_scene(scene, args.save_scene)}", file=sys.stderr)
    built = build_scene(scene, warn=lambda m: print(f"\nwarning: {m}", file=sys.stderr))
    for n in built.notes:
        print(f"note: {n}", file=sys.stderr)
    rt = built.runtime
    if not built.sinks:
        from ..outputs import StdoutWriter

        built.sinks.append(StdoutWriter(live=True, stream=sys.stderr, p99_ms=lambda: rt.latency()["total"]["p99"],
                                        every=4))
    status = LearningStatus()
    readings: list[ForceReading] = []
    limit = args.max_frames if args.max_frames is not None else (scene.max_frames or None)
    stop = SignalStop(rt)

    def on_reading(r: ForceReading) -> None:
        if r.truth_n is not None:
            readings.append(r)
        stop.check()

    try:
        with stop:
            stats = rt.run([*built.sinks, status], max_frames=limit, on_reading=on_reading)
    finally:
        status.close()
        built.close()  # closes every output: an MCAP log gets its summary and footer
    print("\n".join(_summary_lines(stats, rt) + truth_lines(readings)), file=sys.stderr)
    if readings and (plot := replay_plot_path(args.out, scene)) is not None:
        _plot(readings, plot)
        print(f"wrote {plot} (force and truth against time)", file=sys.stderr)
    if stop.signal is not None:
        print(f"run stopped by {stop.signal.name} after {stats.readings} readings; outputs closed", file=sys.stderr)
        return 128 + int(stop.signal)  # 130 SIGINT, 143 SIGTERM: every output complete, but the run was cut short
    if stats.processed == 0:
        why = "; ".join(f"sensor '{s.name}': {s.source.stats.frames} frames read, {s.source.stats.corrupt} corrupt"
                        + (f", {s.error}" if s.error else "") for s in rt.sensors)
        raise SourceError(f"the run produced no reading ({why}); frames must be 320x240 or 240x320 BGR images "
                          "(the DIGIT frame contract)")
    if stats.source_errors == len(rt.sensors):
        raise CheckFailedError("every sensor was lost during the run: "
                               + "; ".join(f"{s.name}: {s.error}" for s in rt.sensors))
    return 0


def replay_plot_path(outs: list[str], scene) -> Path | None:
    """Where ``run`` draws a labelled replay's force and truth against time: next to the first
    reading output, ``<its name>_force_vs_time.png`` (None when the run writes no file)."""
    paths = [Path(o) for o in outs] or [Path(p) for o in getattr(scene, "outputs", [])
                                         if (p := getattr(o, "path", None))]
    if not paths:
        return None
    first = paths[0]
    return first.with_name(f"{first.stem}_{PLOT_NAME}")


# -- demo ---------------------------------------------------------------------------------
@dataclass
class DemoSummary:
    """What the demo measured: error of CNN readings vs ground truth, gate agreement,
    latency percentiles (ms), counts; paths of the plot, readings CSV and this JSON."""

    bundle: str
    readings: int
    contact_readings: int
    error: dict | None
    gate_agreement: float | None
    latency_ms: dict
    flags: dict
    plot: str
    readings_csv: str
    summary_json: str = ""
    notes: list[str] = field(default_factory=list)


def _plot(readings: list[ForceReading], path: Path) -> str:
    """Force over time, truth vs estimate, as PNG (:func:`tactile_force.edge.report.plots.force_vs_time`)."""
    t = np.array([r.timestamp_ns for r in readings], np.float64)
    t = (t - t[0]) / 1e9 if t.size else t
    est = np.array([r.force_n for r in readings], np.float64)
    truth = np.array([np.nan if r.truth_n is None else r.truth_n for r in readings], np.float64)
    return _plot_cv(t, est, truth, path)


def _plot_cv(t: np.ndarray, est: np.ndarray, truth: np.ndarray, path: Path) -> str:
    """The force plot (OpenCV, the package's one plotting module); returns how it was drawn."""
    from ..report.plots import force_vs_time

    force_vs_time(t, est, truth, path)
    return "opencv"


def run_demo(source, bundle: str | os.PathLike, out_dir: str | os.PathLike, threads: int = 1,
             echo=print, every: int = 10, publish_as: str | os.PathLike | None = None) -> DemoSummary:
    """Play ``source`` (a FrameSource whose frames carry truth_n) through the gate and the
    bundle, write readings.csv, force_vs_time.png (:data:`PLOT_NAME`) and summary.json to ``out_dir``
    (the summary names the files under ``publish_as`` when ``out_dir`` is a staging folder moved there)."""
    from ..data.metrics import error_stats
    from ..gate.contact_gate import ContactGate
    from ..model.onnx_model import OnnxForceModel
    from ..outputs import CsvWriter, format_reading
    from ..runtime.loop import ForceRuntime
    from ..runtime.options import RuntimeOptions, Sensor

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    model = OnnxForceModel(bundle, threads=threads)
    rt = ForceRuntime([Sensor("digit", source, ContactGate())], model, RuntimeOptions(report_stale=False))
    readings: list[ForceReading] = []
    csv_path = out / "readings.csv"
    with CsvWriter(csv_path) as csv_out:
        def keep(r: ForceReading) -> None:
            readings.append(r)
            if echo and (Flags.NO_CONTACT not in r.flags) and r.frame_index % every == 0:
                echo(format_reading(r))

        stats = rt.run([csv_out], on_reading=keep)
    rt.close()
    cnn = cnn_readings(readings)
    err = None
    if cnn:
        es = error_stats([r.force_n for r in cnn], [float(r.truth_n or 0.0) for r in cnn])
        err = es.as_dict()
    with_truth = [r for r in readings if r.truth_n is not None and Flags.INVALID_INPUT not in r.flags]
    agree = None
    if with_truth:
        agree = float(np.mean([(Flags.NO_CONTACT not in r.flags) == ((r.truth_n or 0.0) >= 1.0) for r in with_truth]))
    flag_counts: dict[str, int] = {}
    for r in readings:
        for name in r.flags.names() or ["ok"]:
            flag_counts[name] = flag_counts.get(name, 0) + 1
    plot_path = out / PLOT_NAME
    how = _plot(readings, plot_path) if readings else "none"
    final = Path(publish_as) if publish_as is not None else out
    summary = DemoSummary(
        bundle=str(bundle), readings=len(readings), contact_readings=len(cnn), error=err, gate_agreement=agree,
        latency_ms=stats.latency_ms, flags=flag_counts, plot=str(final / PLOT_NAME),
        readings_csv=str(final / "readings.csv"),
        notes=[f"plot drawn with {how}", "error over readings where the CNN ran and truth > 0 N",
               "gate_agreement: share of frames where gate contact == (truth >= 1 N)"],
    )
    summary.summary_json = str(final / "summary.json")
    (out / "summary.json").write_text(json.dumps(asdict(summary), indent=2, default=float) + "\n")
    return summary


def configure_demo(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="tactile_force_demo",
                   help=f"output folder, relative to the working directory ({PLOT_NAME}, readings.csv, summary.json)")
    p.add_argument("--grasps", type=positive_int, default=3, help="grasp sequences the virtual DIGIT plays (>= 1)")
    p.add_argument("--seed", type=int, default=0, help="random seed of the virtual DIGIT")
    p.add_argument("--bundle", default="default", help="model bundle (default: the embedded default model)")
    p.add_argument("--threads", type=positive_int, default=1, help="ONNX Runtime intra-op threads (>= 1)")
    p.add_argument("--force", action="store_true", help="replace --out when it holds an earlier demo's result")


def main_demo(args: argparse.Namespace) -> int:
    from ..scene import default_bundle_path, output_problem

    bundle = default_bundle_path() if args.bundle == "default" else Path(args.bundle)
    if not (bundle / "model.json").is_file():
        raise SceneError(f"--bundle {bundle}: not a bundle folder (expected model.json in it)")
    from ..files.guard import OutputKind, check_output

    out = Path(args.out).absolute()
    # a new or empty folder, or (--force) an earlier demo's result holding nothing else; never the bundle
    check_output(out, [("--bundle", bundle)], force=getattr(args, "force", False), kind=OutputKind.FOLDER,
                 verb="demo")
    if problem := output_problem(out.with_name(f".{out.name}.probe")):  # the staging folder is made beside --out
        raise SceneError(f"--out {out}: {problem}")
    try:
        from ..synthetic import VirtualDigitSource
    except ImportError as exc:
        raise SourceError(f"the demo needs tactile_force.edge.synthetic.VirtualDigitSource ({exc})") from None
    source = VirtualDigitSource(seed=args.seed, n_grasps=args.grasps, fps=60.0)
    print(f"virtual DIGIT: {args.grasps} grasps, seed {args.seed} -> bundle {bundle}")
    from ..files.atomic import staged_folder

    with staged_folder(out, "demo") as tmp:
        s = run_demo(source, bundle, tmp, threads=args.threads, publish_as=out)
    if s.error:
        print(f"error vs truth over {s.error['n']} CNN readings: "
              f"RE {s.error['re_mean']:.3f} +- {s.error['re_std']:.3f}, "
              f"MAE {s.error['mae_mean']:.3f} +- {s.error['mae_std']:.3f} N")
    if s.gate_agreement is not None:
        print(f"gate agrees with truth (contact <=> >= 1 N) on {100 * s.gate_agreement:.1f} % of frames")
    print("latency ms (p50 / p99): " + ", ".join(
        f"{k} {v['p50']:.2f}/{v['p99']:.2f}" for k, v in s.latency_ms.items() if not math.isnan(v["p50"])))
    print(f"flags: {s.flags}")
    print(f"wrote {s.plot}, {s.readings_csv}, {s.summary_json}")
    return 0
