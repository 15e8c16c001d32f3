"""A hand on two cores: eight sensors at 60 fps, phase-shifted by 1/480 s (free-running
cameras) and in phase (synchronised cameras: every step has eight frames ready), with a
step's per-sensor work on one thread (``RuntimeOptions(workers=1)``) and on two
(``workers=2``, what auto picks on a host with two cores), interleaved A/B/B/A per round so
load drifts cancel; ratios divide by the bare session's p50 at 60 fps measured in the same
round.

    python -m benchmarks.workers --out out/benchmarks            # 4 rounds of 600 frames
    python -m benchmarks.workers --quick --out /tmp/workers     # smoke run

Writes ``workers.md`` and ``workers.json`` into ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from .cadence import FPS, HAND, Phase, runtime_phase, setup
from .harness.latency import bare_at_cadence
from .harness.machine import CpuWindow, describe_machine, header
from .harness.stats import markdown_table

WORKERS = (1, 2)
LAYOUTS = {"phase-shifted": True, "in phase": False}


def measure(rounds: int, n: int, prewarm: bool) -> list[dict]:
    """Per round: the reference p50 (ms) and one 8-sensor phase per worker count."""
    pool, bare, model = setup()
    out = []
    for k in range(rounds):
        order = WORKERS if k % 2 == 0 else WORKERS[::-1]
        ref = [bare_at_cadence(bare, min(n, 300), FPS)]
        phases: dict[tuple[str, int], Phase] = {}
        for layout, shifted in LAYOUTS.items():
            for w in order:
                phases[layout, w] = runtime_phase(model, pool, HAND, n, prewarm, workers=w, shifted=shifted)
        ref.append(bare_at_cadence(bare, min(n, 300), FPS))
        r50 = float(np.median(np.concatenate(ref)))
        out.append({"reference_p50_ms": r50, "phases": phases})
        print(f"workers round {k + 1}/{rounds}: reference p50 {r50:.3f} ms; worst p99 / reference "
              + ", ".join(f"{layout} {w} {phases[layout, w].p(99, True) / r50:.2f}" for layout, w in phases),
              flush=True)
    model.close()
    return out


def _span(values: list[float], fmt: str = ".2f") -> str:
    return f"{np.median(values):{fmt}} ({min(values):{fmt}}-{max(values):{fmt}})"


def table(rds: list[dict]) -> str:
    rows = []
    for layout, w in rds[0]["phases"]:
        ph = [r["phases"][layout, w] for r in rds]
        ref = [r["reference_p50_ms"] for r in rds]
        rows.append([layout, w, _span([p.p(50) / r for p, r in zip(ph, ref)]),
                     _span([p.p(99) / r for p, r in zip(ph, ref)]),
                     _span([p.p(99, True) / r for p, r in zip(ph, ref)]),
                     _span([p.p(99, True) for p in ph], ".3f"), _span([100 * p.cpu_share for p in ph], ".1f"),
                     sum(p.readings for p in ph)])
    return markdown_table(["cameras", "workers", "total p50 / ref", "total p99 / ref", "worst sensor p99 / ref",
                           "worst sensor p99 ms", "process CPU %", "readings"], rows)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.workers", description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=Path("out/benchmarks"), help="folder for workers.md / workers.json")
    ap.add_argument("--rounds", type=int, default=4, help="A/B rounds (default 4)")
    ap.add_argument("--prewarm", action="store_true", help="warm-ups on (default off: the cleaner comparison)")
    ap.add_argument("--quick", action="store_true", help="1 round of 120 frames (a smoke run)")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error(f"--rounds {args.rounds}: expected 1 or more")
    rounds, n = (1, 120) if args.quick else (args.rounds, 600)
    window = CpuWindow()
    rds = measure(rounds, n, args.prewarm)
    state = window.stop()
    from tactile_force.edge.files.atomic import staged_file

    args.out.mkdir(parents=True, exist_ok=True)
    record = [{"reference_p50_ms": r["reference_p50_ms"],
               **{f"{layout}, workers={w}": {"total_ms": [p.p(50), p.p(99), p.p(99, True)],
                                              "cpu_share": p.cpu_share, "readings": p.readings}
                  for (layout, w), p in r["phases"].items()}} for r in rds]
    with staged_file(args.out / "workers.json") as tmp:
        tmp.write_text(json.dumps({"rounds": record}, indent=1) + "\n")
    notes = (f"{rounds} rounds; per round the reference (a bare session call at 60 fps, before and after), then "
             f"{HAND} sensors at 60 fps, phase-shifted by 1/480 s and in phase, {n} frames each, with workers=1 and "
             f"workers=2 in alternating order; warm-ups {'on' if args.prewarm else 'off'}. Per cell the median over "
             f"rounds (min-max). While measuring: {state.line()}.")
    cmd = "python -m benchmarks.workers " + " ".join(argv if argv is not None else sys.argv[1:])
    text = header("A hand on two cores: one worker or two", cmd.strip(), describe_machine(), notes)
    text += "\n" + table(rds) + "\n"
    with staged_file(args.out / "workers.md") as tmp:
        tmp.write_text(text)
    print(text)
    print(f"wrote {args.out / 'workers.md'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
