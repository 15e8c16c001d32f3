"""Issue 18, one downscale per frame: the default bundle at the network resolution, its
accuracy, the reductions compared, and the goals measured against the reference graph.

    python -m benchmarks.one_downscale make-default      # rebuild edge/models/default (graph surgery)
    python -m benchmarks.one_downscale accuracy          # RE of reference vs new default, per reduction
    python -m benchmarks one-downscale --out docs/benchmarks   # the page (goals, before/after, 10-run check)

The reference is today's (commit c1733e6) default graph, kept as a loadable format-2 bundle in
benchmarks/reference_graphs/default_c1733e6.onnx (+ .json): a full-resolution uint8 input and
the 4x4 AveragePool inside the graph. The new default is the same graph and weights with that
pool cut off (:func:`tactile_force.export.network_input.network_input_bundle`): it reads the
80 x 60 image the runtime reduces once per frame.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
REFERENCE_GRAPH = REPO / "benchmarks" / "reference_graphs" / "default_c1733e6.onnx"
DEFAULT_DIR = REPO / "edge" / "models" / "default"


def chosen_reduction():
    """The reduction the default bundle records (edge/reduce.py's default at x4)."""
    from tactile_force.edge.reduce import default_reduction

    return default_reduction(4)


def reductions():
    """The exact box averages compared for the one downscale: (label, FrameReduction)."""
    from tactile_force.edge.manifest import FrameReduction, Reduction

    return [("area x4 (one INTER_AREA, ties to even: the reference graph's own rounding)",
             FrameReduction(Reduction.AREA, 4)),
            ("area-2x-steps x4 (two exact 2x2 INTER_AREA, each rounded half up)",
             FrameReduction(Reduction.AREA_2X_STEPS, 4))]


def bundle_errors(model, data) -> object:
    """edge.metrics.ErrorStats of an OnnxForceModel on labelled frames (full-resolution frames
    through ``predict``, which reduces them itself)."""
    from tactile_force.edge.metrics import error_stats

    from .evaluate import predict_all

    return error_stats(predict_all(model, data), data.force)


def accuracy(reds=None) -> list[list[object]]:
    """[[graph, reduction, RE synthetic, MAE synthetic, RE AUROVA, MAE AUROVA], ...] for the
    reference graph and the network-input graph under each reduction."""
    import tempfile

    from tactile_force.edge import OnnxForceModel
    from tactile_force.export.network_input import network_input_bundle

    from .evaluate import real_frames, synthetic_test

    syn, real = synthetic_test(False), real_frames()
    rows = []

    def row(label, red, model):
        s = bundle_errors(model, syn)
        r = bundle_errors(model, real) if real is not None else None
        rows.append([label, red, s.re_mean, s.mae_mean, r.re_mean if r else None, r.mae_mean if r else None])

    row("reference c1733e6 (full-res input, AveragePool in the graph)", "in the graph",
        OnnxForceModel(REFERENCE_GRAPH))
    with tempfile.TemporaryDirectory() as tmp:
        for label, red in (reds or reductions()):
            b = network_input_bundle(REFERENCE_GRAPH, Path(tmp) / red.method.value, red)
            row("network input 80x60 (same weights)", label, OnnxForceModel(b))
    return rows


def make_default(dest: Path = DEFAULT_DIR) -> Path:
    """Rebuild the default bundle: the reference graph cut at the network resolution, the
    chosen reduction recorded, its error re-measured on the synthetic test split."""
    import tempfile

    from tactile_force.edge import OnnxForceModel, load_bundle
    from tactile_force.edge.bundle import write_bundle
    from tactile_force.edge.manifest import ErrorFigures
    from tactile_force.export.network_input import network_input_bundle

    from .evaluate import synthetic_test

    red = chosen_reduction()
    with tempfile.TemporaryDirectory() as tmp:
        b = network_input_bundle(REFERENCE_GRAPH, Path(tmp) / "b", red, name="default-rgbmod-compact-int8")
        syn = synthetic_test(False)
        stats = bundle_errors(OnnxForceModel(b), syn)
        m = b.manifest
        assert m.error is not None
        # The graph's forces changed by the reduction's rounding: re-measured; the fp32 graph's
        # figures stay what they were (it was measured with the in-graph average).
        m.error = replace(m.error, data=f"{syn.source}; reduced by {red.method.value} x{red.factor}",
                          frames=len(syn.force), vs_truth=ErrorFigures(**stats.as_dict()), vs_fp32=None)
        m.provenance.extra = {**m.provenance.extra,
                              "network_input": f"graph surgery of the c1733e6 default (4x4 AveragePool removed, "
                                               f"same weights): python -m benchmarks.one_downscale make-default; "
                                               f"frames reduced by {red.method.value} x{red.factor}"}
        out = write_bundle(dest, b.onnx_path.read_bytes(), m, overwrite=True)
    print(f"wrote {out.path}: synthetic test {stats}")
    return load_bundle(dest).path


def reduction_timings(repeats: int = 2000) -> list[list[object]]:
    """[[how, p50 us, p99 us, max |diff| to the exact average (levels), share of pixels differing]]
    for ways of reducing a 320x240x3 frame to 80x60, timed interleaved (one thread)."""
    from tactile_force.edge.manifest import FrameReduction, Reduction
    from tactile_force.edge.reduce import FrameReducer

    from .stats import percentiles

    cv2.setNumThreads(1)
    from .evaluate import real_frames

    real = real_frames()
    f = real.rgb[0] if real is not None else np.random.default_rng(0).integers(0, 256, (320, 240, 3), np.uint8)
    exact = f.reshape(80, 4, 60, 4, 3).astype(np.float64).mean((1, 3))
    out = np.empty((80, 60, 3), np.uint8)
    mid = np.empty((160, 120, 3), np.uint8)
    acc = np.empty((80, 60, 3), np.uint16)
    area = FrameReducer(FrameReduction(Reduction.AREA, 4), f.shape)
    steps = FrameReducer(FrameReduction(Reduction.AREA_2X_STEPS, 4), f.shape)

    def lin_steps():
        cv2.resize(f, (120, 160), dst=mid, interpolation=cv2.INTER_LINEAR)
        cv2.resize(mid, (60, 80), dst=out, interpolation=cv2.INTER_LINEAR)

    def pyr():
        cv2.pyrDown(f, dst=mid)
        cv2.pyrDown(mid, dst=out)

    def npsum():
        np.add.reduce(f.reshape(80, 4, 60, 4, 3).sum(1, dtype=np.uint16), axis=2, out=acc)
        np.copyto(out, (acc + 8) >> 4, casting="unsafe")

    cands = {
        "cv2.resize INTER_AREA x4 (reduction 'area')": lambda: area(f, out=out),
        "2 x cv2.resize INTER_AREA x2 (reduction 'area-2x-steps')": lambda: steps(f, out=out),
        "2 x cv2.resize INTER_LINEAR at exactly 1/2 (same values as area-2x-steps)": lin_steps,
        "2 x cv2.pyrDown (5x5 Gaussian, not a box average)": pyr,
        "numpy reshape + sum (uint16) + rounding": npsum,
        "cv2.resize INTER_LINEAR x4 (mean of the central 2x2 only)":
            lambda: cv2.resize(f, (60, 80), dst=out, interpolation=cv2.INTER_LINEAR),
    }
    diffs = {}
    for k, fn in cands.items():
        fn()
        d = np.abs(out.astype(np.float64) - exact)
        diffs[k] = (float(d.max()), float((np.abs(out.astype(np.int64) - np.round(exact)) > 0).mean()))
    times = {k: [] for k in cands}
    for _ in range(repeats):
        for k, fn in cands.items():
            t0 = time.perf_counter_ns()
            fn()
            times[k].append((time.perf_counter_ns() - t0) / 1e3)
    rows = []
    for k in cands:
        p = percentiles(times[k])
        rows.append([k, p.p50, p.p99, diffs[k][0], diffs[k][1]])
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.one_downscale", description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("make-default", "accuracy", "reductions"))
    args = ap.parse_args(argv)
    if args.what == "make-default":
        make_default()
    elif args.what == "accuracy":
        for r in accuracy():
            print(" | ".join(f"{c:.4f}" if isinstance(c, float) else str(c) for c in r))
    else:
        for r in reduction_timings():
            print(" | ".join(f"{c:.3f}" if isinstance(c, float) else str(c) for c in r))
    return 0


if __name__ == "__main__":
    sys.exit(main())
