"""One command for every benchmark page.

    python -m benchmarks all --out docs/benchmarks    # quant, stability, into the docs
    python -m benchmarks all --quick                  # smoke run (never into the docs)
    python -m benchmarks stability --shipped-only --out DIR   # stiff / extreme cases, shipped bundles only
    python -m benchmarks robustness --out docs        # bad inputs and faults, counted -> docs/robustness.md
    python -m benchmarks trust --out docs/benchmarks  # frames that cannot be judged, counted -> trust.md
    python -m benchmarks intervals --out docs/benchmarks  # every reading's error bar, measured -> intervals.md
    python -m benchmarks cadence --out docs/benchmarks    # latency at 60 fps, 1 and 8 sensors -> cadence.md
    python -m benchmarks error --out docs/benchmarks      # shipped bundles: error vs run time -> error_vs_runtime.md
    python -m benchmarks instructions --out docs/benchmarks  # instructions per reading (callgrind) -> instructions.md
    python -m benchmarks startup --out docs/benchmarks    # process start -> first reading, per install -> startup.md
    python -m benchmarks footprint --out docs/benchmarks  # cache lines of code and data one reading touches
    python -m benchmarks default-bundle --bench-runs 5 --out docs/benchmarks  # which bundle ships as the default

Results go to ``--out DIR`` (default out/benchmarks, git-ignored); docs/benchmarks only
when it is named. Every page states the command, the commit of the code that measured, the
machine and its load while measuring. The under-1 ms verdict on this host is ``tactile-force
bench`` (the shipped bundles; docs/bench.md). Pages with their own command: ``python -m
benchmarks.calibration``, ``python -m benchmarks.depth_bundles``; the shipped bundles are built by ``python -m
benchmarks.reference``, ``python -m benchmarks.interval_fit`` and ``python -m
benchmarks.virtual_depth_calibration``. From an install (the 'bench' extra) the same is
``python -m tactile_force.benchmarks``; what a robot host runs is ``tactile-force bench``
(no torch) and ``tactile-force study`` (docs/bench.md).
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

from tactile_force.edge.cli.args import within  # noqa: E402
from tactile_force.edge.limits import COUNT, READINGS  # noqa: E402

from .harness.paths import repo_root  # noqa: E402

TASKS = ("quant", "stability", "all")


def docs_dir() -> Path | None:
    """docs/benchmarks of the clone; None when the package is installed."""
    root = repo_root()
    return None if root is None else root / "docs" / "benchmarks"


def default_out() -> Path:
    """out/benchmarks of the clone (git-ignored), else of the working directory."""
    root = repo_root()
    return (root if root is not None else Path.cwd()) / "out" / "benchmarks"


def _write(name: str, text: str, out: Path) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    p = out / name
    p.write_text(text.rstrip() + "\n")
    print(f"wrote {p}")
    return p


def is_docs(out: Path) -> bool:
    """True when ``out`` is (inside) the clone's docs/benchmarks."""
    docs = docs_dir()
    if docs is None:
        return False
    try:
        out.resolve().relative_to(docs.resolve())
    except ValueError:
        return False
    return True


def _problem(args: argparse.Namespace) -> str:
    """What is wrong with the arguments, one line ('' when nothing), before any work: ``--out`` a
    folder (made if missing) that is not a file, ``--before`` an instructions.json of the expected
    shape, each ``--python`` an interpreter."""
    out: Path = args.out
    if out.exists() and not out.is_dir():
        return f"--out {out}: is a file; expected a folder for the pages (made if missing)"
    parent = next((p for p in (out, *out.parents) if p.exists()), None)
    if parent is not None and not os.access(parent, os.W_OK | os.X_OK):
        return f"--out {out}: {parent} is not writable"
    if args.before is not None:
        if args.what != "instructions":
            return "--before: only 'instructions' takes an earlier record"
        from .instructions import read_before

        try:
            read_before(args.before)
        except ValueError as exc:
            return f"--before {args.before}: {exc}"
    if args.reports is not None:
        if args.what != "default-bundle":
            return "--reports: only 'default-bundle' judges earlier bench reports"
        for r in args.reports:
            if not r.is_file():
                return f"--reports {r}: not a file; expected a bench report.json (tactile-force bench --out DIR)"
            try:
                from .bench_contract import read_report

                read_report(r)
            except (ValueError, KeyError, TypeError) as exc:
                return f"--reports {r}: not a bench report.json ({exc})"
    for py in args.python or ():
        if not (os.path.isfile(py) and os.access(py, os.X_OK)):
            return f"--python {py}: not an executable file; expected a Python interpreter (e.g. .venv/bin/python)"
    return ""


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks``; the loggers it quietens are restored when it returns. Exit 2
    with one line for what the benchmarks cannot find or were given wrong."""
    from tactile_force.edge.errors import TactileForceError
    from tactile_force.edge.report.logs import quiet_loggers

    # Latency bundles carry random weights and no data_stats: the runtime's one warning per
    # bundle that its out-of-distribution check is skipped is expected here, every row.
    with quiet_loggers("tactile_force.edge.bundle.data_stats"):
        try:
            return _main(argv)
        except TactileForceError as exc:
            print(f"benchmarks: {exc}", file=sys.stderr)
            return 2


def _main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    ap = argparse.ArgumentParser(prog="python -m benchmarks", description=(__doc__ or "").split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("what", nargs="?", choices=(*TASKS, "robustness", "trust", "intervals", "cadence", "error",
                                               "instructions", "startup", "footprint", "default-bundle"),
                    help="which page to make; 'robustness', 'trust', 'intervals', 'cadence', 'error' and "
                         "'instructions' are not part of 'all'")
    ap.add_argument("--rounds", type=within(int, COUNT), default=3,
                    help="cadence: rounds of interleaved phases (default 3; --quick: 1)")
    ap.add_argument("--bench-runs", type=within(int, COUNT), default=10,
                    help="cadence: runs of the bench verdict on the default bundle (default 10; --quick: 2); "
                         "default-bundle: runs of tactile-force bench (at least 5 for a choice)")
    ap.add_argument("--reports", nargs="+", type=Path, default=None,
                    help="default-bundle: judge these earlier bench report.json files instead of running bench")
    ap.add_argument("--readings", type=within(int, READINGS), default=0,
                    help="instructions, footprint: readings counted per run (default 200 and 20; --quick: 20 and 5)")
    ap.add_argument("--variants", nargs="*", default=None, choices=("default", "d", "rgbmod_d", "rgbmod_int8"),
                    help="instructions, footprint: the shipped bundles to count (default all)")
    ap.add_argument("--paths", nargs="*", default=None, choices=("compiled", "opencv"),
                    help="instructions: the per-frame paths to count (default both: the compiled kernels and the "
                         "robot-side install's OpenCV path)")
    ap.add_argument("--before", type=Path, default=None,
                    help="instructions: an earlier instructions.json: the page shows before / after")
    ap.add_argument("--python", action="append", default=None,
                    help="startup: an interpreter (an install) to measure; repeat for several (default: this one)")
    ap.add_argument("--runs", type=within(int, COUNT), default=3,
                    help="startup: new processes per figure, the median (default 3)")
    ap.add_argument("--write-default-stats", action="store_true",
                    help="trust: also store the default bundle's data_stats in edge/models/default/model.json")
    ap.add_argument("--examples", type=within(int, COUNT), default=100,
                    help="robustness: generated cases per generated category (default 100; --quick: 15)")
    ap.add_argument("--shipped-only", action="store_true",
                    help="stability: only the bundles shipped in edge/models (no torch, no random-weight bundles; "
                         "a few minutes)")
    ap.add_argument("--quick", action="store_true", help="few frames per row: a smoke run, never written to the docs")
    ap.add_argument("--out", type=Path, default=default_out(),
                    help="where tables and plots go (default out/benchmarks; docs/benchmarks only when named)")
    args = ap.parse_args(argv)
    if not args.what:
        ap.print_help()
        return 2
    problem = _problem(args)
    if problem:  # judged before any counting or measuring
        print(f"benchmarks {args.what}: {problem}", file=sys.stderr)
        return 2
    if args.quick and is_docs(args.out):
        print(f"--quick results are a smoke run and never go into the docs: drop --quick or pick another --out "
              f"than {args.out}", file=sys.stderr)
        return 2
    if args.what == "robustness":
        from .robustness import run as run_robustness

        return run_robustness(args, argv)
    if args.what == "trust":
        from .trust import run as run_trust

        return run_trust(args, argv)
    if args.what == "cadence":
        from .cadence import run as run_cadence

        return run_cadence(args, argv)
    if args.what == "error":
        from .error_vs_runtime import run as run_error

        return run_error(args, argv)
    if args.what == "instructions":
        from .instructions import run as run_instructions

        return run_instructions(args, argv)
    if args.what == "default-bundle":
        from .default_bundle import run as run_default_bundle

        return run_default_bundle(args, argv)
    if args.what == "footprint":
        from .footprint import run as run_footprint

        return run_footprint(args, argv)
    if args.what == "startup":
        from .startup import run as run_startup

        return run_startup(args, argv)
    if args.what == "intervals":
        from .intervals import intervals_page

        _write("intervals.md", intervals_page(args, argv), args.out)
        return 0
    todo = TASKS[:-1] if args.what == "all" else [args.what]
    for t in todo:
        if t == "quant":
            from .quantization import run as run_quant

            run_quant(args, argv)
        elif t == "stability":
            from .stability import run as run_stability

            run_stability(args, argv)
    if args.what == "all" or todo:
        from .readme import write_readme

        write_readme(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
