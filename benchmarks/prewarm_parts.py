"""Which parts of the runtime's warm-up pay (an investigation; its answer is kept in
docs/benchmarks/cadence.md): one sensor at 60 fps, the default bundle, warm-ups of each part
alone against none and all, interleaved with the bare-session reference of
:mod:`benchmarks.cadence`.

    python -m benchmarks.prewarm_parts [--rounds 3] [--frames 600]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

import numpy as np

from .cadence import reference, runtime_phase
from .harness.frames import contact_frames
from .harness.latency import BareOnnxRuntime, LatencyCase


def _parts(rt, live, gate: bool, judge: bool, model: bool) -> None:
    from tactile_force.edge.reading import StageLatency

    n = 0
    for s in live:
        lane = rt._lanes[s.name]
        if gate:
            lane.gating.prewarm()
        if lane.inferred and lane.last is not None:
            n += 1
            if judge:
                tf, raw, g = lane.last
                rt._judge.estimate(s.name, tf, raw, g, StageLatency())
    if n and model:
        rt.model.prewarm(n)


VARIANTS: dict[str, tuple[bool, bool, bool] | None] = {
    "none": None, "gate step only": (True, False, False), "model call only": (False, False, True),
    "gate step + model call": (True, False, True), "all (gate step, judge, model call)": (True, True, True)}


def main(argv: list[str] | None = None) -> int:
    import cv2
    from tactile_force.edge import OnnxForceModel, load_bundle
    from tactile_force.edge.runtime.loop import ForceRuntime
    from tactile_force.edge.scene import default_bundle_path

    ap = argparse.ArgumentParser(prog="python -m benchmarks.prewarm_parts")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--frames", type=int, default=600)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    pool = contact_frames()
    path = default_bundle_path()
    bare = BareOnnxRuntime(LatencyCase(None, "fp32", bundle=path), pool)
    model = OnnxForceModel(load_bundle(path), threads=1)
    original: Callable = ForceRuntime._warm_up
    rows: dict[str, list[tuple[float, float, float, float]]] = {k: [] for k in VARIANTS}
    try:
        for k in range(args.rounds):
            for name, parts in VARIANTS.items():
                ref = float(np.median(reference(bare, args.frames)))
                if parts is not None:
                    g, j, m = parts
                    ForceRuntime._warm_up = lambda rt, live, g=g, j=j, m=m: _parts(rt, live, g, j, m)  # type: ignore[method-assign]
                ph = runtime_phase(model, pool, 1, args.frames, prewarm=parts is not None)
                ForceRuntime._warm_up = original  # type: ignore[method-assign]
                rows[name].append((ph.p(50) / ref, ph.p(99) / ref, 100 * ph.cpu_share, ph.overran))
                print(f"round {k + 1} {name}: p50/ref {ph.p(50) / ref:.2f} p99/ref {ph.p(99) / ref:.2f} "
                      f"CPU {100 * ph.cpu_share:.1f} % waited {ph.overran}", flush=True)
    finally:
        ForceRuntime._warm_up = original  # type: ignore[method-assign]
        model.close()
    print("| warm-up | total p50 / reference p50 | total p99 / reference p50 | process CPU % | frames that waited |")
    print("|---|---|---|---|---|")
    for name, v in rows.items():
        a = np.array(v)
        print(f"| {name} | {np.median(a[:, 0]):.2f} ({a[:, 0].min():.2f}-{a[:, 0].max():.2f}) | "
              f"{np.median(a[:, 1]):.2f} ({a[:, 1].min():.2f}-{a[:, 1].max():.2f}) | "
              f"{np.median(a[:, 2]):.1f} | {int(a[:, 3].sum())} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
