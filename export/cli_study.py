"""CLI: ``tactile-force study`` (the 'export' extra) - a quantization study of your fp32 bundle or
checkpoint on your labelled data, measured through the runtime on this host (:mod:`.study`).

Exit 0: a configuration fits the budget (the recommendation is named); 1: none fits on this
host; 2: bad input (a missing bundle or folder, an unusable checkpoint).
"""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

from tactile_force.edge.cli.args import float_in, within
from tactile_force.edge.limits import BUDGET_MS, COUNT, READINGS, THREADS
from tactile_force.edge.typed_json import Check


def configure(p: argparse.ArgumentParser) -> None:
    p.formatter_class = argparse.RawDescriptionHelpFormatter
    p.description = (
        "Which precision to ship for THIS host: quantize your fp32 bundle (or checkpoint) every way - fp32, fp16,\n"
        "int8 dynamic, int8 static x calibration method x per-channel/per-tensor x nodes kept float - and a\n"
        "per-node sensitivity ranking; measure each configuration's error on your labelled data and its latency\n"
        "through the runtime here. Writes study.md, study.json, pareto.png and the Pareto-front bundles to --out.")
    p.epilog = ("examples:\n"
                "  tactile-force study bundles/my_fp32 --data my_presses/ --calib my_calib/ --out study/\n"
                "  tactile-force study checkpoint.pth.tar --variant rgbmod --data my_presses/ --quick --out study/")
    p.add_argument("source", type=Path, help="fp32 bundle folder, or a checkpoint (.pth / .pth.tar)")
    p.add_argument("--data", type=Path, required=True,
                   help="labelled frames in the authors' layout (images/N.png + forces/force_N.txt): the error")
    p.add_argument("--calib", type=Path, help="int8 calibration frames (default: --data itself, noted as such)")
    p.add_argument("--background", type=Path, help="no-contact image of --data's sensor (else learnt, as 'run')")
    p.add_argument("--out", type=Path, default=Path("tactile_force_study"),
                   help="output folder (default tactile_force_study); written whole when the study ends")
    p.add_argument("--force", action="store_true", help="replace --out when it holds an earlier study result")
    p.add_argument("--budget-ms", type=within(float, BUDGET_MS), default=1.0,
                   help="p99 budget for the recommendation (ms)")
    p.add_argument("--threads", type=within(int, THREADS), default=1, help="ONNX Runtime / OpenCV threads (default 1)")
    p.add_argument("--frames", type=within(int, READINGS), default=500, help="latency readings per configuration")
    p.add_argument("--quick", action="store_true", help="a small grid (4 configurations, 3 sensitivity nodes)")
    p.add_argument("--max-configs", type=within(int, Check(ge=0, le=COUNT.le)),
                   help="at most this many configurations besides fp32")
    p.add_argument("--sensitivity-nodes", type=within(int, Check(ge=0, le=COUNT.le)), default=None,
                   help="rank only the first N Conv nodes (default all; --quick: 3; 0: no ranking)")
    p.add_argument("--calib-frames", type=within(int, READINGS), default=200,
                   help="calibration frames at most (default 200)")
    p.add_argument("--keep-all", action="store_true", help="keep every configuration's bundle, not only the front")
    p.add_argument("--variant", help="checkpoint only: the model variant (rgbmod, d, dmod, rgbmod+d)")
    p.add_argument("--width", type=float_in(0.0, 16.0, low_open=True), help="checkpoint only: channel width multiplier")
    p.add_argument("--input-scale", type=float_in(0.0, 1.0, low_open=True),
                   help="checkpoint only: network input scale, e.g. 0.25")


def main(args: argparse.Namespace) -> int:

    from .study import StudyError, StudyOptions, prepare_source, run_study
    from .study_report import table

    if args.sensitivity_nodes is not None and args.sensitivity_nodes < 0:
        raise StudyError(f"--sensitivity-nodes {args.sensitivity_nodes}: expected >= 0")
    for flag, path in (("--data", args.data), ("--calib", args.calib)):
        if path is not None and not path.is_dir():
            raise StudyError(f"{flag} {path}: folder not found (expected the authors' layout: images/N.png + "
                             "forces/force_N.txt)")
    if args.background is not None and not args.background.is_file():
        raise StudyError(f"--background {args.background}: not found (expected a no-contact image)")
    from tactile_force.edge.files.atomic import staged_folder
    from tactile_force.edge.files.guard import OutputKind, check_output

    # --out is study's own result folder: never an input, replaced only with --force and only
    # when it is an earlier study result holding nothing else
    inputs = [("source", args.source), ("--data", args.data), ("--calib", args.calib),
              ("--background", args.background)]
    check_output(args.out, inputs, force=args.force, kind=OutputKind.FOLDER)
    # one replay per configuration: the gate's and data statistics' warnings would repeat for each
    command = "tactile-force study " + " ".join(shlex.quote(a) for a in sys.argv[2:]) \
        if len(sys.argv) > 1 and sys.argv[1] == "study" else "tactile-force study"
    o = StudyOptions(budget_ms=args.budget_ms, threads=args.threads, frames=args.frames, quick=args.quick,
                     max_configs=args.max_configs, sensitivity_nodes=args.sensitivity_nodes,
                     max_calibration_frames=args.calib_frames, keep_bundles="all" if args.keep_all else "pareto")
    from tactile_force.benchmarks.harness.stats import MIN_P99_READINGS
    from tactile_force.edge.report.logs import quiet_loggers

    if args.frames < MIN_P99_READINGS:
        print(f"study: --frames {args.frames} is below the {MIN_P99_READINGS} readings a p99 needs: the figures are "
              "measured, no configuration will be recommended", file=sys.stderr)
    with staged_folder(args.out, "study", force=args.force, inputs=inputs) as tmp:
        fp32 = prepare_source(args.source, tmp / "bundles", args.variant, args.width, args.input_scale,
                              parity_data=args.data)
        with quiet_loggers("tactile_force.edge.bundle", "tactile_force.edge.gate", "tactile_force.edge.runtime"):
            report = run_study(fp32, args.data, tmp, o, calibration=args.calib, background=args.background,
                               command=command.strip(), log=lambda s: print(s, file=sys.stderr), publish_as=args.out)
    head, rows = table(report)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(head)]
    print("  ".join(h.ljust(w) for h, w in zip(head, widths)))
    for r in rows:
        print("  ".join(c.ljust(w) for c, w in zip(r, widths)))
    for s in report.sensitivity[:5]:
        print(f"sensitivity: keeping {s.node} float buys back {100 * s.bought_back:+.0f} % of the int8 error vs fp32")
    why = f" ({report.note})" if report.note else ""
    print(f"recommended (most accurate with p99 <= {args.budget_ms:g} ms): {report.recommended or 'none'}{why}")
    print(f"wrote {args.out / 'study.md'}, {args.out / 'study.json'}, {args.out / 'pareto.png'}; took "
          f"{report.seconds:.0f} s")
    return 0 if report.recommended else 1
