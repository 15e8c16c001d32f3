"""How long before a frame is due the runtime's warm-up should end (an investigation; its
answer is kept in docs/benchmarks/cadence.md): one sensor at 60 fps, the default bundle,
``edge.runtime.prewarm.MARGIN_NS`` of 0.3, 0.15 and 0.05 ms interleaved, each phase after a
bare-session reference phase (:mod:`benchmarks.cadence`).

    python -m benchmarks.prewarm_margin [--rounds 4] [--frames 300]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from .cadence import reference, runtime_phase
from .harness.frames import contact_frames
from .harness.latency import BareOnnxRuntime, LatencyCase

MARGINS_NS = (300_000, 150_000, 50_000)


def main(argv: list[str] | None = None) -> int:
    import cv2
    import tactile_force.edge.runtime.prewarm as prewarm
    from tactile_force.edge import OnnxForceModel, load_bundle
    from tactile_force.edge.scene import default_bundle_path

    ap = argparse.ArgumentParser(prog="python -m benchmarks.prewarm_margin")
    ap.add_argument("--rounds", type=int, default=4)
    ap.add_argument("--frames", type=int, default=300)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    pool = contact_frames()
    path = default_bundle_path()
    bare = BareOnnxRuntime(LatencyCase(None, "fp32", bundle=path), pool)
    model = OnnxForceModel(load_bundle(path), threads=1)
    kept = prewarm.MARGIN_NS
    rows: dict[int, list[tuple[float, float, int, float, int]]] = {m: [] for m in MARGINS_NS}
    try:
        for k in range(args.rounds):
            for m in MARGINS_NS:
                prewarm.MARGIN_NS = m
                ref = float(np.median(reference(bare, args.frames)))
                ph = runtime_phase(model, pool, 1, args.frames, prewarm=True)
                rows[m].append((ph.p(50) / ref, ph.p(99) / ref, ph.overran, 100 * ph.cpu_share, ph.prewarms))
                print(f"round {k + 1} margin {m / 1e6:.2f} ms: p50/ref {rows[m][-1][0]:.2f} p99/ref "
                      f"{rows[m][-1][1]:.2f} waited {ph.overran} CPU {100 * ph.cpu_share:.1f} %", flush=True)
    finally:
        prewarm.MARGIN_NS = kept
        model.close()
    print("| margin ms | total p50 / reference p50 | total p99 / reference p50 | frames that waited | process CPU % |")
    print("|---|---|---|---|---|")
    for m, v in rows.items():
        a = np.array(v)
        print(f"| {m / 1e6:.2f} | {np.median(a[:, 0]):.2f} ({a[:, 0].min():.2f}-{a[:, 0].max():.2f}) | "
              f"{np.median(a[:, 1]):.2f} ({a[:, 1].min():.2f}-{a[:, 1].max():.2f}) | "
              f"{int(a[:, 2].sum())} of {int(a[:, 4].sum())} | {np.median(a[:, 3]):.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
