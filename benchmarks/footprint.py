"""What one reading touches (footprint.md): the distinct cache lines of code and of data a
``ForceRuntime`` reading and the bare graph's call read or write, per stage and per shipped bundle.

At a sensor's cadence the core rests between frames and its caches go cold: a reading then pays
for every line of code and data it touches, not for the instructions it executes. This counts
those lines with valgrind's callgrind and its cache simulator, the same on any host and load: per
reading, first a 128 MB sweep through memory evicts everything (counting off), then the reading
runs (counting on) against an empty last-level cache of 32 MB (16-way, 64-byte lines; first-level
caches of 1 kB, so the sweep leaves no line of the reading in them either). Every line the reading
touches then misses the last level once and only once: its instruction misses (ILmr) are the
distinct code lines, its data misses (DLmr + DLmw) the distinct data lines. The set-up, imports
and warm-up are the instructions benchmark's (benchmarks/instructions.py: the same worker
``_Setup``, one sensor, in-memory frames, warm-ups off) and are not counted.

    python -m benchmarks footprint --out docs/benchmarks     # -> footprint.md + .json
    python -m benchmarks footprint --quick                   # a smoke run (few readings)

Where valgrind is not installed, or the host is not x86-64, the command says so and exits 0.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import re
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .harness import callgrind

#: the caches simulated: first levels small (the sweep empties them), the last level large enough that a
#: reading never evicts its own lines (a reading touches a few MB at most)
CACHES = ["--I1=1024,2,64", "--D1=1024,2,64", "--LL=33554432,16,64"]
SWEEP_BYTES = 128 << 20  # four times the last level: LRU leaves none of what was there before
LINE = 64
READINGS = 20  # readings counted per mode (--quick: 5)
EVENTS = ("Ir", "ILmr", "DLmr", "DLmw")


def _sweep(buf: np.ndarray) -> None:
    """Touch every 64-byte line of ``buf`` once (a write: the line comes in and goes dirty)."""
    buf[::LINE] += 1


def worker(argv: list[str]) -> int:
    """``python -m benchmarks.footprint --worker BUNDLE FRAMES MODES N``: set up as the instructions
    worker does, then per mode N times: sweep (not counted), one reading (counted); one dump per mode."""
    import cv2

    from .harness.client_requests import (
        DUMP_STATS_AT,
        START_INSTRUMENTATION,
        TOGGLE_COLLECT,
        ZERO_STATS,
        on_valgrind,
        request,
    )
    from .instructions import MODES, WARMUP, _Setup

    cv2.setNumThreads(1)
    bundle, frames, modes, n = Path(argv[0]), Path(argv[1]), argv[2].split(","), int(argv[3])
    on_valgrind()
    setup = _Setup(bundle, frames, n if "runtime" in modes else 0)
    buf = np.zeros(SWEEP_BYTES, np.uint8)
    for m in MODES:
        for _ in range(WARMUP if m != "runtime" else 0):
            setup.once(m)
    for _ in range(WARMUP):
        setup.once("runtime")
    request(START_INSTRUMENTATION)  # from here the caches are simulated; counting only around readings
    for mode in modes:
        gc.collect()
        name = np.frombuffer(mode.encode() + b"\0", np.uint8).copy()
        request(ZERO_STATS)
        for _ in range(n):
            _sweep(buf)
            request(TOGGLE_COLLECT)
            setup.once(mode)
            request(TOGGLE_COLLECT)
        request(DUMP_STATS_AT, int(name.ctypes.data))
    return 0


@dataclass
class Lines:
    """Per reading: instructions, distinct code lines and distinct data lines touched."""

    instructions: float
    code_lines: float
    data_lines: float

    @property
    def kib(self) -> float:
        return (self.code_lines + self.data_lines) * LINE / 1024


@dataclass
class VariantLines:
    """One bundle on one per-frame path: mode -> :class:`Lines`."""

    bundle: str
    label: str
    path: str
    modes: dict[str, Lines]


@dataclass
class Record:
    """footprint.json."""

    command: str
    commit: str
    cpu: str
    machine: str
    readings: int
    valgrind: str
    caches: list[str]
    variants: list[VariantLines] = field(default_factory=list)
    seconds: float = 0.0


def _totals(path: Path) -> dict[str, int]:
    """The event totals of one callgrind dump (its ``summary:`` / ``totals:`` line)."""
    events: list[str] = []
    totals: list[int] = []
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split(":", 1)[1].split()
            elif line.startswith(("summary:", "totals:")):
                totals = [int(x) for x in line.split(":", 1)[1].split()]
    return dict(zip(events, totals))


def count_variant(bundle: Path, label: str, frames: Path, readings: int, tmp: Path, path: str,
                  log=print) -> VariantLines:
    """Count one bundle's runtime, bare call, gate and (where it has one) depth stage on ``path``."""
    from tactile_force.edge.bundle.manifest import InputKind
    from tactile_force.edge.bundle.store import read_manifest

    from .instructions import PATH_SUFFIX, PATHS, _env

    has_depth = read_manifest(bundle / "model.json").input(InputKind.DEPTH) is not None
    modes = ["runtime", "bare", "gate"] + (["depth"] if has_depth else [])
    vg = callgrind.valgrind()
    assert vg is not None
    out = tmp / f"footprint.{bundle.name}.{path}.out"
    cmd = [vg, "--tool=callgrind", f"--callgrind-out-file={out}", "--simulate-cache=yes", *CACHES,
           "--compress-strings=no", "--compress-pos=no", "--dump-line=no", "--separate-threads=yes",
           "--instr-atstart=no", "--collect-atstart=no", sys.executable, "-m",
           f"{__package__ or 'benchmarks'}.footprint", "--worker", str(bundle), str(frames), ",".join(modes),
           str(readings)]
    t = time.monotonic()
    proc = subprocess.run(cmd, env={**_env(), "TACTILE_FORCE_KERNELS": PATHS[path]}, capture_output=True, text=True,
                          timeout=3600)
    if proc.returncode != 0:
        raise RuntimeError(f"{label}: the footprint worker failed: {proc.stderr.strip()[-600:]}")
    got: dict[str, Lines] = {}
    for part in sorted(out.parent.glob(f"{out.name}.*-01")):
        trigger = next((ln for ln in open(part, encoding="utf-8", errors="replace") if ln.startswith("desc: Trigger:")),
                       "")
        m = re.search(r"Client Request: (\w+)", trigger)
        if m:
            e = _totals(part)
            got[m.group(1)] = Lines(e.get("Ir", 0) / readings, e.get("ILmr", 0) / readings,
                                    (e.get("DLmr", 0) + e.get("DLmw", 0)) / readings)
    missing = set(modes) - set(got)
    if missing:
        raise RuntimeError(f"{label}: no footprint of {', '.join(sorted(missing))} in the worker's run")
    log(f"  {label}{PATH_SUFFIX[path]}: " + ", ".join(f"{m} {got[m].code_lines:.0f} code + {got[m].data_lines:.0f} "
                                                      "data lines" for m in modes)
        + f" ({time.monotonic() - t:.0f} s)")
    return VariantLines(bundle.name, label + PATH_SUFFIX[path], path, got)


def page(rec: Record) -> str:
    """footprint.md from the record."""
    from .harness.stats import markdown_table

    rows = []
    for v in rec.variants:
        r, b = v.modes["runtime"], v.modes["bare"]
        own_code, own_data = r.code_lines - b.code_lines, r.data_lines - b.data_lines
        rows.append([v.label, f"{r.code_lines:.0f}", f"{r.data_lines:.0f}", f"{r.kib:.0f}", f"{b.code_lines:.0f}",
                     f"{b.data_lines:.0f}", f"{b.kib:.0f}", f"{own_code:+.0f}", f"{own_data:+.0f}",
                     f"{r.kib / b.kib:.2f}x"])
    stage_rows = []
    for v in rec.variants:
        for mode, x in v.modes.items():
            stage_rows.append([v.label, mode, f"{x.instructions / 1e6:.3f}", f"{x.code_lines:.0f}",
                               f"{x.data_lines:.0f}", f"{x.kib:.0f}"])
    out = ["# What one reading touches", "", f"Command: `{rec.command}`", "", f"Commit: {rec.commit}", "",
           f"CPU: {rec.cpu}. Machine: {rec.machine}.", "",
           f"Counted by {rec.valgrind}'s callgrind with its cache simulator ({' '.join(rec.caches)}): before each of "
           f"{rec.readings} readings per mode a 128 MB sweep (not counted) empties the simulated caches, so every line "
           "the reading touches misses the last level once: its instruction misses are the distinct lines of code, its "
           "data misses the distinct lines of data (64 bytes each), the same on any host and load "
           "(benchmarks/footprint.py). 'runtime': one `ForceRuntime.step` (one sensor, in-memory frames, warm-ups "
           "off); 'bare': one `InferenceSession.run` of the bundle's graph on the same inputs; 'gate': the gate step "
           "alone; 'depth': the depth stage alone. 'compiled': the `fast` extra's kernels; 'OpenCV path': the "
           "robot-side install's calls.", "",
           "## Per reading: the runtime against its bare call", "",
           markdown_table(["bundle", "runtime code lines", "runtime data lines", "runtime kB", "bare code lines",
                           "bare data lines", "bare kB", "the runtime's own code lines", "its own data lines",
                           "runtime / bare (bytes)"], rows), "",
           "## Per stage", "",
           markdown_table(["bundle", "stage", "instructions (M)", "code lines", "data lines", "kB"], stage_rows), "",
           f"Counting took {rec.seconds:.0f} s.", ""]
    return "\n".join(out) + "\n"


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """``python -m benchmarks footprint``: count, write footprint.json then .md to ``args.out``."""
    from .harness.machine import command_line, describe_machine
    from .harness.paths import source_commit, write_record_and_page
    from .instructions import PATHS, VARIANTS, _frames_file, models_dir

    why = callgrind.unavailable("footprint")
    if why:
        print(why, file=sys.stderr)
        return 0
    readings = args.readings if args.readings else (5 if args.quick else READINGS)
    t0 = time.monotonic()
    variants = []
    with tempfile.TemporaryDirectory(prefix="footprint-") as d:
        tmp = Path(d)
        frames = _frames_file(tmp)
        for path in args.paths or PATHS:
            for name, label in VARIANTS:
                if args.variants is None or name in args.variants:
                    variants.append(count_variant(models_dir() / name, label, frames, readings, tmp, path))
    m = describe_machine()
    rec = Record(command_line(argv), source_commit(), m.cpu, m.line(), readings, callgrind.version(), CACHES,
                 variants, time.monotonic() - t0)
    write_record_and_page(args.out, "footprint", json.dumps(asdict(rec), indent=1) + "\n", page(rec))
    print(f"wrote {args.out / 'footprint.md'}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        os.environ.setdefault("OMP_NUM_THREADS", "1")
        sys.exit(worker(sys.argv[2:]))
    print("usage: python -m benchmarks footprint [--readings N] [--out DIR]", file=sys.stderr)
    sys.exit(2)
