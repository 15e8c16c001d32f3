"""Instructions per bare model call, counted by valgrind's callgrind (load-independent).

    python -m benchmarks.bare_instructions edge/models/rgbmod_int8 edge/models/default [--calls 200]

For each bundle: one onnxruntime session (the package's :func:`session_options`, one
thread) fed one reduced synthetic frame (batch 1, the bundle's network input) is run under
callgrind, ``--calls`` calls after the set-up and warm-up, those calls alone counted
(callgrind's client requests, :mod:`.harness.client_requests`, x86-64); their count over
``--calls`` is the work of one call. Instruction counts
move only when the code or the graph does (the same on a loaded or an idle host of one
instruction set); they say nothing of the time an instruction takes on a given CPU.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

from .harness import callgrind

WARMUP_CALLS = 5


def _child(bundle: str, calls: int) -> None:
    """Set up a bare session and run ``calls`` calls, those alone counted (the measured process)."""
    import numpy as np
    import onnxruntime as ort
    from tactile_force.edge.bundle.store import load_bundle
    from tactile_force.edge.model.onnx_model import bundle_session_options

    from .harness.client_requests import Segment, on_valgrind

    on_valgrind()  # the request compiled before anything is counted
    b = load_bundle(bundle)
    sess = ort.InferenceSession(str(b.onnx_path), bundle_session_options(b, 1), providers=["CPUExecutionProvider"])
    rng = np.random.default_rng(0)
    feed = {}
    for spec in b.manifest.inputs:
        shape = [1, *spec.shape[1:]]
        feed[spec.name] = rng.integers(0, 256, shape, dtype=np.uint8)
    out = [o.name for o in sess.get_outputs()]
    for _ in range(WARMUP_CALLS):
        sess.run(out, feed)
    with Segment("bare"):
        for _ in range(calls):
            sess.run(out, feed)


def instructions_per_call(bundle: str | os.PathLike, calls: int = 200) -> float:
    """Instructions of one bare batch-1 call of ``bundle`` (callgrind, ``calls`` calls counted
    alone)."""
    from .harness.client_requests import SUPPORTED

    if not SUPPORTED:
        raise RuntimeError("instruction counts here need callgrind's client requests, made on x86-64 only")
    with tempfile.TemporaryDirectory() as tmp:
        prof = callgrind.run_segments([sys.executable, "-m", f"{__package__ or 'benchmarks'}.bare_instructions",
                                       "--child", str(bundle), "--calls", str(calls)], Path(tmp) / "cg.out",
                                      {**os.environ, "OMP_NUM_THREADS": "1"})
    return prof["bare"].total / calls


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
