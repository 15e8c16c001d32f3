"""One command for every benchmark table and plot.

    python -m benchmarks --check                      # the under-1 ms check; exit 1 if it fails
    python -m benchmarks latency                      # latency matrix -> out/benchmarks/latency.md
    python -m benchmarks all --out docs/benchmarks    # everything, into the docs (only when asked)
    python -m benchmarks all --quick                  # smoke run (never into the docs)
    python -m benchmarks robustness --out docs        # bad inputs and faults, counted -> docs/robustness.md
    python -m benchmarks trust --out docs/benchmarks  # frames that cannot be judged, counted -> trust.md
    python -m benchmarks intervals --out docs/benchmarks  # every reading's error bar, measured -> intervals.md

Results go to ``--out DIR`` (default out/benchmarks, git-ignored); docs/benchmarks only
when it is named. Every page states the machine, its load while measuring, and the command.
From an install (the 'bench' extra) the same is ``python -m tactile_force.benchmarks``; what a
robot host runs is ``tactile-force bench`` (no torch) and ``tactile-force study`` (docs/bench.md).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

# torch's OpenMP workers busy-wait after each call by default; on a 2-core host that spinning
# steals the core from every row measured after a PyTorch-eager row. Sleep instead.
os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")
os.environ.setdefault("KMP_BLOCKTIME", "0")

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs" / "benchmarks"
DEFAULT_OUT = REPO / "out" / "benchmarks"
TASKS = ("latency", "error", "quant", "stability", "all")


def _write(name: str, text: str, out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    p = out / name
    p.write_text(text.rstrip() + "\n")
    print(f"wrote {p}")
    return p


def is_docs(out: Path) -> bool:
    """True when ``out`` is (inside) docs/benchmarks."""
    try:
        out.resolve().relative_to(DOCS.resolve())
    except ValueError:
        return False
    return True


def cmd_check(args, argv) -> int:
    from .check import run_check
    from .machine import command_line, describe_machine, header

    res = run_check(frames=200 if args.quick else 1000, budget_ms=args.budget_ms, repeats=args.repeats,
                    pause_s=args.pause_s)
    print(res.report())
    m = describe_machine()
    _write("check.md", header("The under-1 ms check", command_line(argv), m,
                              "Best RGBmod end-to-end p99 through `ForceRuntime` (in-memory source; total = frame "
                              "arrival -> reading: gate + inference + the loop; one thread, int8, frames in contact) "
                              f"against a {args.budget_ms:g} ms budget. Exit status 0 PASS, 1 over budget or no "
                              "verdict (every attempt over budget on a busy machine: 'machine busy').")
           + "```\n" + res.report() + "\n```", args.out)
    return 0 if res.passed else 1


def cmd_latency(args, argv) -> None:
    from .latency import measure
    from .latency_page import latency_page

    _write("latency.md", latency_page(args, argv, measure), args.out)


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks``; the loggers it quietens are restored when it returns."""
    from tactile_force.edge.report.logs import quiet_loggers

    # Latency bundles carry random weights and no data_stats: the runtime's one warning per
    # bundle that its out-of-distribution check is skipped is expected here, every row.
    with quiet_loggers("tactile_force.edge.bundle.data_stats"):
        return _main(argv)


def _main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("what", nargs="?", choices=(*TASKS, "robustness", "trust", "intervals"),
                    help="which benchmark to run (default: none with --check); 'robustness', 'trust' and "
                         "'intervals' are not part of 'all'")
    ap.add_argument("--write-default-stats", action="store_true",
                    help="trust: also store the default bundle's data_stats in edge/models/default/model.json")
    ap.add_argument("--examples", type=int, default=100,
                    help="robustness: generated cases per generated category (default 100; --quick: 15)")
    ap.add_argument("--check", action="store_true", help="run the under-1 ms check; exit 1 when it fails")
    ap.add_argument("--budget-ms", type=float, default=1.0, help="--check budget for the end-to-end total p99 (ms)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="--check: attempts at most; a new one only after one over budget on a busy machine")
    ap.add_argument("--pause-s", type=float, default=30.0, help="--check: seconds to wait before a repeat")
    ap.add_argument("--quick", action="store_true", help="few frames per row: a smoke run, never written to the docs")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT,
                    help="where tables and plots go (default out/benchmarks; docs/benchmarks only when named)")
    args = ap.parse_args(argv)
    if not args.what and not args.check:
        ap.print_help()
        return 2
    if args.quick and is_docs(args.out):
        print(f"--quick results are a smoke run and never go into the docs: drop --quick or pick another --out "
              f"than {args.out}", file=sys.stderr)
        return 2
    if args.repeats < 1 or args.pause_s < 0:
        print(f"--repeats {args.repeats} / --pause-s {args.pause_s}: expected >= 1 attempts and >= 0 s",
              file=sys.stderr)
        return 2
    if args.what == "robustness":
        from .robustness import run as run_robustness

        return run_robustness(args, argv)
    if args.what == "trust":
        from .trust import run as run_trust

        return run_trust(args, argv)
    if args.what == "intervals":
        from .interval_page import intervals_page

        _write("intervals.md", intervals_page(args, argv), args.out)
        return 0
    todo = TASKS[:-1] if args.what == "all" else ([args.what] if args.what else [])
    rc = 0
    if args.check:  # first, in a fresh process: torch / OpenVINO thread pools of later rows cannot disturb it
        rc = cmd_check(args, argv)
    for t in todo:
        if t == "latency":
            cmd_latency(args, argv)
        elif t == "error":
            from .error_vs_runtime import run as run_error

            run_error(args, argv)
        elif t == "quant":
            from .quant_study import run as run_quant

            run_quant(args, argv)
        elif t == "stability":
            from .stability import run as run_stability

            run_stability(args, argv)
    if args.what == "all" or todo:
        from .readme import write_readme

        write_readme(args.out)
    return rc


if __name__ == "__main__":
    sys.exit(main())
