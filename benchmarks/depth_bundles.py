"""The depth bundles page (depth_bundles.md): the shipped compact depth bundles (edge/models/d,
edge/models/rgbmod_d) measured as users run them.

    python -m benchmarks.depth_bundles [--frames 2000] [--test-frames 0] [--write docs/benchmarks/depth_bundles.md]

1. Error on the synthetic test split (held-out indenters, benchmarks.reference) through
   ``ForceRuntime``: per grasp a runtime whose contact gate learnt that grasp's no-contact
   frame (the virtual DIGIT rendered with the grasp's LED gains), the bundle's own depth stage
   (built from its manifest's depth record: 80 x 60 grid) and the bundle; RE and MAE over the
   frames the runtime gave a force for, with the frames it flagged counted.
2. The compact RGBmod+D runtime total p50 against the compact RGBmod's (the default bundle),
   one thread, interleaved in one run: each step of one runtime is followed by a step of the
   other on the same frame, so both see the same machine load; the ratio is the figure
   (goal: <= 1.5). The D bundle is interleaved too.

No torch is needed for the measurement (the test split's frames come from the reference
dataset, rendered by the virtual DIGIT on first use and cached in benchmarks/cache).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .harness.frames import contact_frames
from .harness.machine import describe_machine, header
from .harness.sources import ListSource, MemorySource


@dataclass
class RuntimeError_:
    """RE / MAE (N) through ForceRuntime on ``n`` frames with a force; ``flagged``: frames
    the runtime gave no force for (no contact, mismatch, invalid)."""

    bundle: str
    n: int
    flagged: int
    re_mean: float
    mae_mean: float
    re_std: float
    mae_std: float


def _test_split(limit: int = 0):
    """(frames (N,320,240,3) uint8, forces (N,), led gains per frame, grasp id per frame)."""
    from . import reference

    root = reference.ensure_dataset()  # rendered once (virtual DIGIT, no torch) and cached
    data = reference.load_arrays(root)
    idx = data.select("test")
    if limit:
        idx = idx[:limit]
    gains = [tuple(float(v) for v in (data.meta[i].get("led_gain") or (1.0, 1.0, 1.0))) for i in idx]
    grasps = [(data.meta[i].get("seed"), data.meta[i].get("grasp"), gains[k]) for k, i in enumerate(idx)]
    return data.rgb[idx], data.force[idx].astype(np.float64), gains, grasps


def runtime_error(bundle_dir: Path, frames: np.ndarray, forces: np.ndarray, gains: list, grasps: list,
                  threads: int = 1) -> RuntimeError_:
    """Error of ``bundle_dir`` on labelled frames through ForceRuntime (see module doc)."""
    from tactile_force.edge import ContactGate, OnnxForceModel, load_bundle
    from tactile_force.edge.data.metrics import error_stats
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    bundle = load_bundle(bundle_dir)
    model = OnnxForceModel(bundle, threads=threads)
    digit = VirtualDigit(VirtualDigitOptions())
    order: dict[tuple, list[int]] = {}
    for i, g in enumerate(grasps):
        order.setdefault(g, []).append(i)
    pred = np.full(len(forces), np.nan)
    for key, members in order.items():
        bg = digit.render(None, 0.0, led_gain=key[2], rng=np.random.default_rng(0)).frame
        gate = ContactGate()
        gate.capture_background([bg])
        src = ListSource([frames[i] for i in members], [float(forces[i]) for i in members])
        rt = ForceRuntime([Sensor("s", src, gate)], model, RuntimeOptions(threads=threads, deadline_ms=1e9),
                          owns_model=False)
        for r in iter_readings(rt):
            if math.isfinite(r.raw_force_n):
                pred[members[r.frame_index]] = r.raw_force_n
        rt.close()
    model.close()
    ok = np.isfinite(pred)
    st = error_stats(pred[ok], forces[ok])
    return RuntimeError_(bundle_dir.name, int(ok.sum()), int((~ok).sum()), float(st.re_mean), float(st.mae_mean),
                         float(st.re_std), float(st.mae_std))


def iter_readings(rt):
    while not rt.finished:
        yield from rt.step()


def interleaved_p50(bundles: list[Path], frames: int = 2000, warmup: int = 50, threads: int = 1) -> dict[str, dict]:
    """Runtime total p50/p99 (ms) of each bundle, interleaved step by step on the same contact
    frames (:func:`benchmarks.harness.frames.contact_frames`), one thread."""
    import cv2
    from tactile_force.edge import ContactGate, OnnxForceModel, load_bundle
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor, build_depth_stage

    cv2.setNumThreads(threads)
    pool = contact_frames(64, seed=0)
    n = warmup + frames
    rts, totals, depth_ms, gate_ms, inf_ms = [], [], [], [], []
    for b in bundles:
        bundle = load_bundle(b)
        gate = ContactGate()
        gate.capture_background(pool.background)
        m = bundle.manifest
        factory = (lambda m=m: build_depth_stage(None, m)) if m.needs_depth else None
        rts.append(ForceRuntime([Sensor("s", MemorySource(pool.rgb, n), gate)], OnnxForceModel(bundle, threads=threads),
                                RuntimeOptions(threads=threads, deadline_ms=1e9, latency_window=16),
                                depth_factory=factory))
        for arr in (totals, depth_ms, gate_ms, inf_ms):
            arr.append(np.full(n, np.nan))
    while not all(rt.finished for rt in rts):
        for k, rt in enumerate(rts):
            for r in rt.step():
                if r.frame_index >= 0 and not r.flags & (Flags.STALE | Flags.NO_CONTACT | Flags.INVALID_INPUT):
                    totals[k][r.frame_index] = r.latency.total_ms
                    depth_ms[k][r.frame_index] = r.latency.depth_ms
                    gate_ms[k][r.frame_index] = r.latency.gate_ms
                    inf_ms[k][r.frame_index] = r.latency.inference_ms
    out = {}
    for b, rt, t, d, g, i in zip(bundles, rts, totals, depth_ms, gate_ms, inf_ms):
        rt.close()
        ok = np.isfinite(t[warmup:])

        def p50(x: np.ndarray, ok: np.ndarray = ok) -> float:
            return float(np.percentile(x[warmup:][ok], 50))

        out[str(b)] = {"p50": p50(t), "p99": float(np.percentile(t[warmup:][ok], 99)), "gate_p50": p50(g),
                       "depth_p50": p50(d), "inference_p50": p50(i), "n": int(ok.sum())}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.depth_bundles", description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2000, help="interleaved runtime steps per bundle (default 2000)")
    ap.add_argument("--test-frames", type=int, default=0, help="limit the test split (0: all)")
    ap.add_argument("--write", type=Path, help="write the markdown page here")
    args = ap.parse_args(argv)
    for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(v, "1")
    from tactile_force.edge import shipped_bundles

    shipped = shipped_bundles()
    missing = [k for k in ("default", "d", "rgbmod_d") if k not in shipped]
    if missing:
        raise SystemExit(f"shipped bundles missing: {missing}")
    lines = ["| bundle | frames with a force | flagged | RE mean | MAE mean (N) |", "|---|---|---|---|---|"]
    frames, forces, gains, grasps = _test_split(args.test_frames)
    for name in ("default", "d", "rgbmod_d"):
        e = runtime_error(shipped[name], frames, forces, gains, grasps)
        lines.append(f"| {name} | {e.n} | {e.flagged} | {e.re_mean:.3f} | {e.mae_mean:.3f} |")
    del frames
    lat = interleaved_p50([shipped["default"], shipped["d"], shipped["rgbmod_d"]], frames=args.frames)
    base = lat[str(shipped["default"])]["p50"]
    lines += ["", "| bundle (interleaved, one thread) | total p50 ms | total p99 ms | gate p50 ms | depth p50 ms | "
              "inference p50 ms | total p50 / RGBmod total p50 |", "|---|---|---|---|---|---|---|"]
    for path, v in lat.items():
        name = Path(path).name
        lines.append(f"| {name} | {v['p50']:.3f} | {v['p99']:.3f} | {v['gate_p50']:.3f} | {v['depth_p50']:.3f} | "
                     f"{v['inference_p50']:.3f} | {v['p50'] / base:.2f} |")
    machine = describe_machine()
    text = "\n".join(lines)
    print(text)
    print(f"\nmachine: {machine.line()}; {machine.background_load}")
    if args.write:
        cmd = "python -m benchmarks.depth_bundles" + (f" --frames {args.frames}" if args.frames != 2000 else "") \
            + f" --write {args.write}"
        notes = (__doc__ or "").split("\n\n", 1)[1].rstrip()
        args.write.write_text(header("Shipped compact depth bundles", cmd, machine, notes) + text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
