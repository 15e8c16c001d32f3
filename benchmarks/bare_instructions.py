"""Instructions per bare model call, counted by valgrind's callgrind (load-independent).

    python -m benchmarks.bare_instructions edge/models/default edge/models/fast [--calls 200]

For each bundle: one onnxruntime session (the package's :func:`session_options`, one
thread) fed one reduced synthetic frame (batch 1, the bundle's network input) is run under
callgrind twice, ``--calls`` calls and 0 calls after the same set-up and warm-up; the
difference of the two totals over ``--calls`` is the work of one call. Instruction counts
move only when the code or the graph does (the same on a loaded or an idle host of one
instruction set); they say nothing of the time an instruction takes on a given CPU.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

WARMUP_CALLS = 5


def _child(bundle: str, calls: int) -> None:
    """Set up a bare session and run ``calls`` calls (the measured process)."""
    import numpy as np
    import onnxruntime as ort
    from tactile_force.edge.bundle.store import load_bundle
    from tactile_force.edge.model.onnx_model import session_options

    b = load_bundle(bundle)
    sess = ort.InferenceSession(str(b.onnx_path), session_options(1), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(0)
    feed = {}
    for spec in b.manifest.inputs:
        shape = [1, *spec.shape[1:]]
        feed[spec.name] = rng.integers(0, 256, shape, dtype=np.uint8)
    out = [o.name for o in sess.get_outputs()]
    for _ in range(WARMUP_CALLS):
        sess.run(out, feed)
    for _ in range(calls):
        sess.run(out, feed)


def _total(bundle: str, calls: int, work: Path) -> int:
    out = work / f"cg-{calls}.out"
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", sys.executable, "-m",
           "benchmarks.bare_instructions", "--child", bundle, "--calls", str(calls)]
    run = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, "OMP_NUM_THREADS": "1"})
    if run.returncode != 0:
        raise RuntimeError(f"callgrind run failed: {run.stderr[-2000:]}")
    m = re.search(r"^summary:\s+(\d+)", out.read_text(), re.M) or re.search(r"^totals:\s+(\d+)", out.read_text(), re.M)
    if m is None:
        raise RuntimeError(f"{out}: no totals line")
    return int(m.group(1))


def instructions_per_call(bundle: str | os.PathLike, calls: int = 200) -> float:
    """Instructions of one bare batch-1 call of ``bundle`` (callgrind, difference of a run of
    ``calls`` calls and a run of 0)."""
    if shutil.which("valgrind") is None:
        raise RuntimeError("valgrind is not installed: instruction counts need callgrind")
    with tempfile.TemporaryDirectory() as tmp:
        n = _total(str(bundle), calls, Path(tmp))
        z = _total(str(bundle), 0, Path(tmp))
    return (n - z) / calls


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bare_instructions", description=__doc__.split("\n\n")[0])
    ap.add_argument("bundles", nargs="+", help="bundle folders")
    ap.add_argument("--calls", type=int, default=200, help="calls in the measured run (default 200)")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.child:
        _child(args.bundles[0], args.calls)
        return 0
    base = None
    for b in args.bundles:
        per = instructions_per_call(b, args.calls)
        base = base or per
        print(f"{b}: {per / 1e6:.3f} M instructions per bare call ({per / base:.2f}x the first)", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
