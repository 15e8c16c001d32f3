"""``tactile-force compress``: distil a trained model into the sub-millisecond tier (needs the 'export' extra)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tactile_force.edge.cli.args import float_in, within
from tactile_force.edge.errors import TactileForceError
from tactile_force.edge.limits import BUDGET_MS, COUNT, READINGS, SEED, THREADS


def configure(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("teacher", help="trained model: a .pth checkpoint (the authors' format or ours) or an fp32 "
                                        "RGBmod bundle folder")
    parser.add_argument("--frames", nargs="+", required=True, metavar="PATH",
                        help="UNLABELLED frames: folders of 320x240 images, videos, authors'-layout datasets, "
                             "'tactile-force record' output (several allowed)")
    parser.add_argument("--out", required=True, help="output folder: bundle/ (the chosen student), work/ (cache, "
                                                     "students; a rerun resumes from it), compress.json")
    parser.add_argument("--labels", default=None,
                        help="labelled frames (authors' layout): half mixed into training, half for evaluation")
    parser.add_argument("--budget-ms", type=within(float, BUDGET_MS), default=1.0,
                        help="p99 budget of one batch-2 inference on this host, ms (default 1.0)")
    parser.add_argument("--seed", type=within(int, SEED), default=0, help="seed for splits, training and augmentation")
    parser.add_argument("--ladder", default=None,
                        help="students as WIDTHxK list, e.g. 0.125x8,0.25x4; WIDTHxKbNNNN for fewer residual blocks "
                             "per stage, e.g. 0.25x4b1111 (default: 0.125x8,0.25x4b1111,0.25x4,0.5x4b1111,0.5x4,"
                             "0.25x2)")
    parser.add_argument("--epochs", type=within(int, COUNT), default=30,
                        help="training epochs per student (default 30)")
    parser.add_argument("--max-frames", type=within(int, READINGS), default=6000,
                        help="unlabelled frames used at most (default 6000)")
    parser.add_argument("--no-augment", action="store_true", help="no LED gain/offset, noise and shift augmentation")
    parser.add_argument("--threads", type=within(int, THREADS), default=None,
                        help="torch threads for training (default: all cores)")
    parser.add_argument("--max-vs-teacher-re", type=float_in(0.0, 1e9, low_open=True), default=0.25,
                        help="largest RE against the teacher (held-out unlabelled frames) a student may have to be "
                             "written (default 0.25); when none is within it, no bundle is written (exit code 1)")
    parser.add_argument("--force", action="store_true",
                        help="replace the finished result (bundle/, compress.json) of an earlier compress in --out "
                             "(its trained students in work/ are reused)")
    parser.add_argument("--background", default=None,
                        help="no-contact frame of the --frames sensor: the bundle's data statistics then also record "
                             "contact sizes (without it: colours only, the out-of-distribution check)")


#: what compress writes in --out: everything else there is the user's and never touched
COMPRESS_ENTRIES = ("work", "bundle", "compress.json", "students.png")


def check_compress_folder(out: Path, force: bool) -> None:
    """Refuse an ``--out`` that is not compress's own: a folder holding other files, or a
    finished result (``compress.json``) without ``--force``. An interrupted run's folder (only
    ``work/``) is resumed."""
    from tactile_force.edge.files.guard import OutputRefused

    if not out.is_dir():
        return
    from tactile_force.edge.files.claim import CLAIM_INSIDE

    ours = {*COMPRESS_ENTRIES, CLAIM_INSIDE}
    foreign = sorted(e.name for e in out.iterdir()  # also the hidden siblings its atomic writes leave when killed
                     if e.name not in ours and not any(e.name.startswith(f".{n}.") for n in ours))
    if foreign:
        shown = ", ".join(foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
        raise OutputRefused(f"--out {out}: holds files that compress did not write ({shown}); expected a new folder "
                            "or an earlier compress --out")
    if (out / "compress.json").exists() and not force:
        raise OutputRefused(f"--out {out}: holds a finished compress result (compress.json, bundle/); pass --force "
                            "to replace it (the trained students in work/ are reused), or give a new folder")


def students_plot(students: list[dict], budget_ms: float, out: str) -> Path:
    """``<out>/students.png``: each student's error (RE vs the labels when given, else vs the
    teacher) against its p99, the budget line (:func:`tactile_force.edge.report.plots.error_vs_latency`)."""
    from tactile_force.edge.report.plots import ParetoPoint, error_vs_latency

    labelled = all("vs_labels" in r for r in students)
    key = "vs_labels" if labelled else "vs_teacher"
    pts = [ParetoPoint(r["name"], float(r["p99_ms"]), float(r[key]["re_mean"])) for r in students]
    return error_vs_latency(pts, budget_ms, Path(out) / "students.png",
                            ylabel="RE vs labels" if labelled else "RE vs teacher", title="compress students")


def main(args: argparse.Namespace) -> int:
    from tactile_force.edge.files.guard import OutputKind, check_output

    # --out is compress's own folder (a rerun resumes from it); it must not be, hold or lie in an input
    check_output(args.out, [("teacher", args.teacher), ("--labels", args.labels),
                            ("--background", getattr(args, "background", None))]
                 + [("--frames", f) for f in args.frames], kind=OutputKind.FOLDER, allow_existing=True)
    from tactile_force.edge.files.claim import OutputClaim

    # one compress per --out (a second would train into the same work/), judged under the claim
    with OutputClaim(args.out, "compress", inside=True):
        check_compress_folder(Path(args.out), force=getattr(args, "force", False))
        return _compress_claimed(args)


def _compress_claimed(args: argparse.Namespace) -> int:
    """:func:`main` once ``--out`` is claimed and judged."""
    from tactile_force.edge.errors import BundleError

    from .checkpoint import CheckpointError
    from .compress import (
        DEFAULT_LADDER,
        CompressError,
        CompressOptions,
        compress_model,
        parse_ladder,
    )
    from .training import Augment

    try:
        if args.epochs < 1 or args.max_frames < 20:
            raise CompressError("--epochs must be >= 1 and --max-frames >= 20")
        options = CompressOptions(teacher=args.teacher, frames=args.frames, out=args.out, labels=args.labels,
                                  budget_ms=args.budget_ms, seed=args.seed,
                                  ladder=parse_ladder(args.ladder) if args.ladder is not None else DEFAULT_LADDER,
                                  epochs=args.epochs, max_frames=args.max_frames, threads=args.threads,
                                  augment=None if args.no_augment else Augment(),
                                  show_progress=True, background=args.background,
                                  max_vs_teacher_re=args.max_vs_teacher_re)
        result = compress_model(options)
    except (CompressError, CheckpointError, BundleError) as exc:
        print(f"tactile-force compress: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"tactile-force compress: interrupted; no result written (finished students are kept in "
              f"{args.out}/work and a rerun of the same command resumes)", file=sys.stderr)
        raise
    except TactileForceError:
        raise
    print("students, costliest first (p99 on this host); 'step': the RE each step down the ladder adds, against "
          "the next costlier student (the first: against the teacher)")
    for r in sorted(result.students, key=lambda r: -float(r["p99_ms"])):
        labels = f", vs labels RE {r['vs_labels']['re_mean']:.3f}" if "vs_labels" in r else ""
        blocks = "/".join(f"{v:.3f}" for v in r.get("p99_blocks_ms", []))
        limit = "" if r.get("within_error_limit", True) else f" (above the {args.max_vs_teacher_re:g} RE limit)"
        step = r.get("step", {})
        step_l = f", vs labels {step['vs_labels_re']:+.3f}" if step.get("vs_labels_re") is not None else ""
        print(f"{r['name']:>24}: p99 {r['p99_ms']:.3f} ms (median of blocks {blocks}), vs teacher RE "
              f"{r['vs_teacher']['re_mean']:.3f} MAE {r['vs_teacher']['mae_mean']:.3f} N{limit}{labels}; step from "
              f"{step.get('from', '?')}: vs teacher {step.get('vs_teacher_re', float('nan')):+.3f}{step_l}"
              f"{' (resumed)' if r.get('resumed') else ''}")
    if result.students:
        print(f"wrote {students_plot(result.students, args.budget_ms, args.out)} (students' error vs p99, budget line)")
    if result.bundle is None:
        fits = [r for r in result.students if r["p99_ms"] <= args.budget_ms]
        why = (f"no student fits the {args.budget_ms:g} ms budget on this host" if not fits else
               f"every student within the {args.budget_ms:g} ms budget is further from the teacher than "
               f"--max-vs-teacher-re {args.max_vs_teacher_re:g} (train longer, more frames, a wider student)")
        print(f"tactile-force compress: {why}; no bundle written; students are in {args.out}/work, summary "
              f"{result.summary_path}", file=sys.stderr)
        return 1
    assert result.chosen is not None
    print(f"chose {result.chosen['name']} (most accurate within {args.budget_ms:g} ms p99); wrote {result.bundle.path}")
    return 0
