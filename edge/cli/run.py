"""CLI: ``tactile-force run``: a scene, or one sensor from flags, streamed to readings.

``run`` takes a scene file (``--scene``) or builds the same scene from flags (``--source``
...). Exit codes follow :mod:`tactile_force.edge.cli`: 0 success, 1 a check failed (every
sensor lost mid-run), 2 bad input (a scene or flag, a missing file, a run that produced no
reading).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
from typing import TextIO

from ..errors import CheckFailedError, SceneError, SourceError
from ..interrupts import raise_pending
from ..limits import FPS, FRAME_COUNT
from ..reading import Flags, ForceReading
from ..report.plots import nice_ticks  # noqa: F401 - re-exported (tests, older callers)
from .args import within
from .replay_report import plot_force, replay_plot_path, truth_lines


def configure(p: argparse.ArgumentParser) -> None:
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
    p.add_argument("--fps", type=within(float, FPS), help="with --source: camera rate, or pace a replay at this rate")
    p.add_argument("--name", default="sensor", help="with --source: the sensor's name in readings (default: sensor)")
    p.add_argument("--out", action="append", default=[], metavar="FILE",
                   help="with --source: also write readings to FILE.csv, FILE.jsonl or FILE.mcap (repeatable)")
    p.add_argument("--mcap-frames", action="store_true",
                   help="with --out FILE.mcap: also log each frame (JPEG) and its contact mask (PNG) there")
    p.add_argument("--ros2", metavar="TOPIC", help="with --source: publish readings on this ROS 2 topic")
    p.add_argument("--zenoh", nargs="?", const="tcp/localhost:7447", metavar="ENDPOINT",
                   help="with --source: publish readings to ROS 2 nodes on rmw_zenoh through the Zenoh router at "
                        "ENDPOINT (default tcp/localhost:7447; see docs/ros2.md)")
    p.add_argument("--zenoh-topic", metavar="TOPIC",
                   help="with --zenoh: the force topic (default tactile/force, under --zenoh-namespace)")
    p.add_argument("--zenoh-namespace", metavar="NS", help="with --zenoh: the node's namespace (default /)")
    p.add_argument("--zenoh-node", metavar="NAME", help="with --zenoh: the node's name (default tactile_force)")
    p.add_argument("--zenoh-mode", choices=("client", "peer"),
                   help="with --zenoh: client (default: all through the router) or peer")
    p.add_argument("--zenoh-retry", action="store_true",
                   help="with --zenoh: if no router answers, keep running (the other outputs get every reading) "
                        "and keep trying to reach it")
    p.add_argument("--save-scene", metavar="FILE", help="write the scene that runs as a TOML file")
    p.add_argument("--max-frames", type=within(int, FRAME_COUNT), default=None,
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








def _delivery(sinks: list, readings: int) -> tuple[list[str], bool]:
    """One line per network output (Zenoh, ROS 2 topic: what it published and dropped), and whether
    every output the run was given delivered nothing while there were readings (files always
    deliver; the terminal's reading lines are not an output given)."""
    lines, nothing = [], []
    for s in sinks:
        if not hasattr(s, "published"):
            continue
        topics = getattr(s, "topics", None)
        where = " ".join(str(x) for x in (getattr(s, "endpoint", None), topics.force if topics is not None else
                                          getattr(s, "topic", None)) if x)
        dropped = int(getattr(s, "dropped", 0))
        lines.append(f"output {type(s).__name__} {where}: published {s.published}, dropped {dropped}"
                     + (" - DELIVERED NOTHING" if readings and not s.published else ""))
        nothing.append(bool(readings) and not s.published)
    from ..outputs import StdoutWriter

    # what the run was asked to deliver to: the terminal's lines are beside every output, not one
    outputs = [s for s in sinks if not isinstance(s, StdoutWriter)]
    only_network = bool(outputs) and all(hasattr(s, "published") for s in outputs)
    return lines, only_network and all(nothing)


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
        raise_pending()  # a signal a library swallowed while the scene was built: no run starts
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

    zenoh_flags = ("zenoh_topic", "zenoh_namespace", "zenoh_node", "zenoh_mode")
    given = [f"--{k.replace('_', '-')}" for k in ("bundle", "background", "fps", "ros2", "depth_mapping", "zenoh",
                                                  *zenoh_flags)
             if getattr(args, k, None) is not None] + (["--out"] if args.out else []) \
        + [f"--{k.replace('_', '-')}" for k in ("mcap_frames", "zenoh_retry") if getattr(args, k, False)]
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
    zenoh = None
    if getattr(args, "zenoh", None) is not None:
        zenoh = {"endpoint": args.zenoh, "topic": args.zenoh_topic, "namespace": args.zenoh_namespace,
                 "node": args.zenoh_node, "mode": args.zenoh_mode, "retry": args.zenoh_retry or None}
    elif without := [f for f in given if f.startswith("--zenoh-")]:
        raise SceneError(f"{', '.join(without)}: only with --zenoh [ENDPOINT]")
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
                             depth_mapping=getattr(args, "depth_mapping", None), zenoh=zenoh)
    from ..scene.kinds import kind_of

    if kind_of(scene.sensors[0]).live:
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


def main(args: argparse.Namespace) -> int:
    from ..files.guard import OutputKind, check_output
    from ..scene import build_scene, save_scene
    from ..scene.preflight import scene_inputs

    scene = _run_scene(args)
    inputs = [(f, p) for f, p in [*scene_inputs(scene, args.scene), ("--source", args.source),
                                  ("--bundle", args.bundle), ("--background", args.background),
                                  ("--depth-mapping", getattr(args, "depth_mapping", None))]
              if p not in (None, "default")]
    force = getattr(args, "force", False)
    if (plot := replay_plot_path(args.out, scene)) is not None:  # drawn when the replay has truth: an output too
        check_output(plot, inputs, force=force, kind=OutputKind.FILE, flag="the force-vs-time plot")
    if args.save_scene:
        check_output(args.save_scene, inputs, force=force, kind=OutputKind.FILE, flag="--save-scene")
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

    from ..report.keep_up import KeepUpWatch

    keep_up = KeepUpWatch()
    try:
        with stop:
            stats = rt.run([*built.sinks, status, keep_up], max_frames=limit, on_reading=on_reading)
    finally:
        status.close()
        built.close()  # closes every output: an MCAP log gets its summary and footer
    delivery, delivered_nothing = _delivery(built.sinks, stats.readings)
    print("\n".join(_summary_lines(stats, rt) + [s for s in [keep_up.summary()] if s] + delivery
                    + truth_lines(readings)), file=sys.stderr)
    if readings and (plot := replay_plot_path(args.out, scene)) is not None:
        from ..sources import ReplayFolderSource, VideoFileSource

        unpaced = all(isinstance(s.source, (ReplayFolderSource, VideoFileSource)) and s.source.fps is None
                      for s in rt.sensors)  # its stamps say when a frame was processed, not when it was taken
        plot_force(readings, plot, by_index=unpaced)
        print(f"wrote {plot} (force and truth against {'the frame index' if unpaced else 'time'})", file=sys.stderr)
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
    if delivered_nothing:
        raise CheckFailedError(f"no output delivered any of the run's {stats.readings} readings: "
                               + "; ".join(delivery))
    return 0




# -- demo ---------------------------------------------------------------------------------










