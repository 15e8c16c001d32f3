"""CLI: ``tactile-force bench`` - does each bundle meet its latency budget on this host, at what error?

Each bundle is measured back to back and at the sensor's cadence (``--fps``, frames arriving
that many times a second); the verdict is judged at the cadence.

Core install only (no torch): the work is :mod:`tactile_force.benchmarks.bench`. Exit codes
follow :mod:`tactile_force.edge.cli`: 0 every bundle within budget, 1 any over budget or no
verdict (machine busy, too few readings), 2 bad input (a missing bundle, an unusable --data /
--background, an --out that exists without --force or is an input), 130 / 143 interrupted
(``--out`` left as it was).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from ..errors import TactileForceError
from ..limits import BUDGET_MS, COUNT, FPS, PAUSE_S, READINGS, THREADS
from .args import within


class BenchInputError(TactileForceError):
    """A ``tactile-force bench`` argument is unusable (exit 2); the message names it."""


def cadence_seconds(cadence_frames: int, fps: float) -> float:
    """Seconds one bundle spends at the cadence: the runtime's warm-up and warm-up trial, the readings,
    then the graph alone as often (the one formula of the help and the run's header)."""
    from tactile_force.benchmarks.bench import WARMUP
    from tactile_force.benchmarks.harness.latency import auto_trial_frames

    return (2 * cadence_frames + WARMUP + auto_trial_frames(fps)) / fps


def configure(p: argparse.ArgumentParser) -> None:
    from tactile_force.benchmarks.harness.stats import MIN_P99_READINGS as FLOOR

    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = (
        "Measure bundles through the runtime on THIS host, twice: back to back (frames there when asked for) and at\n"
        "the sensor's cadence (--fps frames a second, the core idle in between, as your controller sees them);\n"
        "judge the latency budget on the end-to-end total p99 AT THE CADENCE:\n"
        "  tactile-force bench                                  # every shipped bundle\n"
        "  tactile-force bench --bundle my_int8 my_fp32         # your bundles\n"
        "  tactile-force bench --bundle B --data LABELLED_DIR --background NO_CONTACT.png   # + error (RE, MAE)\n"
        "  tactile-force bench --fps 30 --cadence-frames 1000   # a 30 fps sensor, 1000 readings at it "
        f"(~{cadence_seconds(1000, 30.0):.0f} s each)\n"
        "At 60 fps the default 300 cadence readings (with the runtime's warm-up trial, then the graph alone as\n"
        f"often) take ~{cadence_seconds(300, 60.0):.0f} s per bundle, on top of the "
        f"back-to-back run; a p99 verdict needs >= {FLOOR} readings at the cadence (back to back is not judged).\n"
        "Writes report.json (docs/bench.md), report.md and pareto.png (error vs p99 at the cadence) to --out.\n"
        "Exit 0 every bundle within budget, 1 any over budget or machine busy (no verdict), 2 bad input.")
    p.add_argument("--bundle", nargs="+", metavar="B", help="bundle folder(s) to measure (default: every shipped "
                                                            "bundle)")
    p.add_argument("--data", type=Path, help="labelled folder in the authors' layout (images/N.png + "
                                             "forces/force_N.txt, e.g. from record or synth): adds error vs truth")
    p.add_argument("--background", type=Path, help="with --data: the sensor's no-contact image (else learnt from "
                                                   "the first frames, as 'run' does)")
    p.add_argument("--threads", type=within(int, THREADS), default=1, help="ONNX Runtime / OpenCV threads (default 1)")
    p.add_argument("--budget-ms", type=within(float, BUDGET_MS), default=1.0,
                   help="budget for the end-to-end total p99 in ms (default 1.0)")
    p.add_argument("--frames", type=within(int, READINGS), default=1000,
                   help="readings measured back to back per bundle (default 1000)")
    p.add_argument("--fps", type=within(float, FPS), default=60.0,
                   help="the sensor's cadence: frames arriving per second per sensor (default 60, a DIGIT's); the "
                        "verdict is judged at it")
    p.add_argument("--cadence-frames", type=within(int, READINGS), default=300,
                   help=f"readings measured at --fps per bundle (default 300: ~{cadence_seconds(300, 60.0):.0f} s per "
                        f"bundle at 60 fps, warm-up, trial and the graph alone included; >= {FLOOR} for a p99 verdict)")
    p.add_argument("--repeats", type=within(int, COUNT), default=3,
                   help="attempts at most; a new one only after one over budget on a busy machine (default 3)")
    p.add_argument("--pause-s", type=within(int, PAUSE_S), default=30, help="seconds before a repeat (default 30)")
    p.add_argument("--out", type=Path, default=Path("tactile_force_bench"),
                   help="output folder (default tactile_force_bench); written whole when the bench ends")
    p.add_argument("--force", action="store_true", help="replace --out when it holds an earlier bench result")


def _check_args(args: argparse.Namespace) -> list[Path]:
    bundles = [Path(b) for b in args.bundle] if args.bundle else None
    if bundles is None:
        from ..scene import shipped_bundles

        bundles = list(shipped_bundles().values())
        if not bundles:
            raise BenchInputError("no shipped bundle found in this install; give --bundle B")
    for b in bundles:
        if not (b / "model.json").is_file():
            raise BenchInputError(f"--bundle {b}: not a bundle folder (expected model.json in it)")
    if args.background is not None and args.data is None:
        raise BenchInputError("--background: only with --data (the labelled frames it belongs to)")
    if args.data is not None and not args.data.is_dir():
        raise BenchInputError(f"--data {args.data}: folder not found (expected the authors' layout: images/N.png + "
                              "forces/force_N.txt)")
    if args.data is not None:  # its frames judged now, as the replay will (before any measurement)
        from ..errors import SourceError
        from ..sources import ReplayFolderSource

        try:
            src = ReplayFolderSource(args.data)
        except SourceError as exc:
            raise BenchInputError(f"--data: {exc}") from None
        src.close()
        if not src.true_forces():
            raise BenchInputError(f"--data {args.data}: no frame with a true force (expected the authors' layout: "
                                  "images/N.png + forces/force_N.txt, e.g. from 'tactile-force record' or 'synth')")
    if args.background is not None:  # decoded now, as the replay will, not after the latency runs
        from ..errors import SourceError
        from ..sources import load_background

        try:
            load_background(args.background)
        except (SourceError, OSError) as exc:
            raise BenchInputError(f"--background {args.background}: {exc}") from None
    from ..files.guard import OutputKind, check_output

    # --out is bench's own result folder: never an input, replaced only with --force and only when
    # it is an earlier bench result holding nothing else
    check_output(args.out, _inputs(args, bundles), force=args.force, kind=OutputKind.FOLDER)
    return bundles


def _inputs(args: argparse.Namespace, bundles: list[Path]) -> list[tuple[str, Path | None]]:
    return [("--bundle", b) for b in bundles] + [("--data", args.data), ("--background", args.background)]


def main(args: argparse.Namespace) -> int:
    from tactile_force.benchmarks.bench import run_bench, text_table, write_report
    from tactile_force.benchmarks.harness.stats import MIN_P99_READINGS

    from ..files.atomic import staged_folder
    from ..report.host import cpu_line
    from ..report.logs import quiet_loggers

    bundles = _check_args(args)
    # The bench frames are virtual DIGIT frames: a bundle made for another sensor would only
    # warn about its data statistics on every row; the figures are latency, not accuracy.
    command = "tactile-force bench " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "bench" else "tactile-force bench"
    each_s = cadence_seconds(args.cadence_frames, args.fps)
    print(f"bench: {len(bundles)} bundle(s), {args.frames} frames each back to back and {args.cadence_frames} at "
          f"{args.fps:g} fps (~{each_s:.1f} s each, the graph alone at the cadence included), "
          f"{args.threads} "
          f"thread(s), budget {args.budget_ms:g} ms at {args.fps:g} fps"
          + (f", error on {args.data}" if args.data else ""), file=sys.stderr)
    if args.cadence_frames < MIN_P99_READINGS:
        print(f"bench: --cadence-frames {args.cadence_frames} is below the {MIN_P99_READINGS} readings a p99 verdict "
              "needs: the figures are measured, the verdict will be 'too few readings'", file=sys.stderr)
    # claimed before measuring: a second run into --out is refused, an earlier result proved now
    with staged_folder(args.out, "bench", force=args.force, inputs=_inputs(args, bundles)) as tmp:
        with quiet_loggers("tactile_force.edge.bundle.data_stats"):
            report = run_bench(bundles, frames=args.frames, threads=args.threads, budget_ms=args.budget_ms,
                               data=args.data, background=args.background, repeats=args.repeats,
                               pause_s=float(args.pause_s), command=command.strip(), fps=args.fps,
                               cadence_frames=args.cadence_frames)
        names = [p.name for p in write_report(report, tmp)]
    print(text_table(report))
    print(cpu_line(report.machine.cpu, report.machine.cores))  # the host every figure above was measured on
    print(f"Per-frame image work: {report.image_path}")
    from ..model.int8_host import host_adds_in_16_bits

    if host_adds_in_16_bits():
        print("Int8 graphs with 8-bit weights run unfused on this CPU (x86-64 without VNNI: the fused kernels could "
              "saturate; docs/runtime.md)")
    print("wrote " + ", ".join(str(args.out / n) for n in names))
    return 0 if report.passed else 1
