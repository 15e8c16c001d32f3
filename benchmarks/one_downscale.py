"""Issue 18, one downscale per frame: the default bundle at the network resolution, its
accuracy, the reductions compared, and the goals measured against the reference graph.

    python -m benchmarks.one_downscale make-default      # rebuild edge/models/default (graph surgery)
    python -m benchmarks.one_downscale accuracy          # RE of reference vs new default, per reduction
    python -m benchmarks.one_downscale gate              # the contact gate's cost, stage by stage
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
from typing import TYPE_CHECKING

import cv2
import numpy as np

if TYPE_CHECKING:
    from tactile_force.edge.data.metrics import ErrorStats

REPO = Path(__file__).resolve().parents[1]
REFERENCE_GRAPH = REPO / "benchmarks" / "reference_graphs" / "default_c1733e6.onnx"
DEFAULT_DIR = REPO / "edge" / "models" / "default"


def chosen_reduction():
    """The reduction the default bundle records (edge/gate/reduce.py's default at x4)."""
    from tactile_force.edge.gate.reduce import default_reduction

    return default_reduction(4)


def reductions():
    """The exact box averages compared for the one downscale: (label, FrameReduction)."""
    from tactile_force.edge.bundle.manifest import FrameReduction, Reduction

    return [("area x4 (one INTER_AREA, ties to even: the reference graph's own rounding)",
             FrameReduction(Reduction.AREA, 4)),
            ("area-2x-steps x4 (two exact 2x2 INTER_AREA, each rounded half up)",
             FrameReduction(Reduction.AREA_2X_STEPS, 4))]


def bundle_errors(model, data) -> ErrorStats:
    """edge.metrics.ErrorStats of an OnnxForceModel on labelled frames (full-resolution frames
    through ``predict``, which reduces them itself)."""
    from tactile_force.edge.data.metrics import error_stats

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
    from tactile_force.edge.bundle.manifest import ErrorFigures
    from tactile_force.edge.bundle.store import write_bundle
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
    from tactile_force.edge.bundle.manifest import FrameReduction, Reduction
    from tactile_force.edge.gate.reduce import FrameReducer

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
    times: dict[str, list[float]] = {k: [] for k in cands}
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


# ----------------------------------------------------------------------------- the goals

#: Issue 18's goals: (what, stage, statistic, limit as a multiple of the reference bare p50).
GOALS = (("runtime total p50", "total", "p50", 0.80),
         ("runtime total p99", "total", "p99", 1.70),
         ("gate p50", "gate", "p50", 0.12))
#: What the issue measured at commit c1733e6 (idle 2-core AMD EPYC host), as ratios to the bare p50.
BEFORE_ISSUE = {"runtime total p50": "1.61 - 1.80", "runtime total p99": "2.56 - 2.75", "gate p50": "0.44 - 0.50"}


def interleaved(frames: int = 2000, warmup: int = 200) -> dict:
    """One run, one thread, frames in contact from memory: per frame, in turn, (1) a
    ``ForceRuntime`` step with the default bundle (graph at the network resolution, one
    downscale shared by gate and model), (2) a bare onnxruntime session on the reference graph
    (c1733e6, full-resolution input: the yardstick), (3) a ``ForceRuntime`` step with the
    reference graph as its bundle (the full-resolution path, today's runtime code).
    Returns {'after': {stage: samples ms}, 'before': {...}, 'bare': samples ms, 'machine': state}."""
    from tactile_force.edge import ContactGate, OnnxForceModel
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime.loop import ForceRuntime, RuntimeOptions, Sensor

    from .frames import frame_pool
    from .graph_profile import bare_session
    from .latency import MemorySource
    from .machine import CpuWindow

    cv2.setNumThreads(1)
    pool = frame_pool()
    n = warmup + frames
    runtimes, samples = {}, {}
    for key, bundle in (("after", DEFAULT_DIR), ("before", REFERENCE_GRAPH)):
        gate = ContactGate()
        gate.capture_background(pool.background)
        runtimes[key] = ForceRuntime([Sensor("bench", MemorySource(pool.rgb, n), gate)],
                                     OnnxForceModel(bundle, threads=1),
                                     RuntimeOptions(threads=1, deadline_ms=1e9, latency_window=16, grabbers=False))
        samples[key] = np.full((n, 4), np.nan)
    bare_sess = bare_session(REFERENCE_GRAPH)
    bare = np.full(n, np.nan)
    window = CpuWindow()
    for i in range(n):
        for key in ("after", "bare", "before"):
            if key == "bare":
                f = pool.rgb[i % len(pool.rgb)][None]
                t0 = time.perf_counter_ns()
                bare_sess.run(None, {"rgb": f})
                bare[i] = (time.perf_counter_ns() - t0) / 1e6
                continue
            for r in runtimes[key].step():
                if r.frame_index >= 0 and not r.flags & (Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.STALE):
                    L = r.latency
                    samples[key][r.frame_index] = (L.gate_ms, L.inference_ms, L.total_ms,
                                                   L.total_ms - L.gate_ms - L.inference_ms)
    state = window.stop()
    for rt in runtimes.values():
        rt.close()
    out = {k: {st: v[warmup:, j] for j, st in enumerate(("gate", "inference", "total", "glue"))}
           for k, v in samples.items()}
    return {**out, "bare": bare[warmup:], "machine": state}


def goal_rows(run: dict) -> list[list[object]]:
    """[[goal, limit, before (issue, c1733e6), before (this run), after (this run), met]] as
    ratios to the reference bare p50 of the same run."""
    from .stats import percentiles

    ref = percentiles(run["bare"]).p50
    rows = []
    for what, stage, stat, limit in GOALS:
        before = getattr(percentiles(run["before"][stage]), stat) / ref
        after = getattr(percentiles(run["after"][stage]), stat) / ref
        rows.append([what, f"<= {limit:.2f}", BEFORE_ISSUE[what], before, after, "yes" if after <= limit else "NO"])
    return rows


def stage_rows(run: dict) -> list[list[object]]:
    """[[path, stage, p50 ms, p99 ms, p50 / reference p50, contact frames]]."""
    from .stats import percentiles

    ref = percentiles(run["bare"])
    rows = [["reference graph, bare onnxruntime session", "inference", ref.p50, ref.p99, 1.0, ref.n]]
    for key, label in (("before", "reference graph through ForceRuntime (full-resolution path)"),
                       ("after", "default bundle through ForceRuntime (one downscale, 80x60 graph)")):
        for st in ("gate", "inference", "glue", "total"):
            p = percentiles(run[key][st])
            rows.append([label, st, p.p50, p.p99, p.p50 / ref.p50, p.n])
    return rows


def gate_rows(frames: int = 2000, warmup: int = 200) -> list[list[object]]:
    """The contact gate stage by stage, one thread, frames in contact from memory:
    [[stage, when it runs, p50 us, p99 us, p50 share of the whole gate]].

    One gate runs ``update``'s stages one by one (its own methods, in update's order) and the
    judging checks that run only on some frames (timed on every frame here, so each row says
    what the check costs when it runs); a second gate runs the whole per-frame path the
    runtime calls (reduce + exposure check + update) on another frame of the pool, both
    interleaved frame by frame, each frame cold in the cache as a camera's would be.
    """
    from tactile_force.edge import ContactGate, load_bundle
    from tactile_force.edge.bundle.data_stats import DataStatsCheck
    from tactile_force.edge.frames import exposure_problem
    from tactile_force.edge.gate import checks as chk

    from .frames import frame_pool
    from .stats import percentiles

    cv2.setNumThreads(1)
    pool = frame_pool()
    a, b = ContactGate(), ContactGate()
    a.capture_background(pool.background)
    b.capture_background(pool.background)
    stats = DataStatsCheck(load_bundle(DEFAULT_DIR).manifest.data_stats, "default")

    def motion_basis(f):
        a._ref.refreshed()
        return a._ref.motion()

    every = "every frame"
    stages = [
        ("one downscale (edge/gate/reduce.py, area-2x-steps)", every, lambda f: a.reduce(f)),
        ("exposure check (all-dark / all-white / clipped)", every, lambda f: exposure_problem(a._small)),
        ("blur + 20x15 thumbnail", every, lambda f: a._prepare(f)),
        ("photometric fit (gain/offset, two residual passes)", every, lambda f: a._fit_thumb(a._thumb)),
        ("changed-pixel mask", every, lambda f: a._changed(a._work)),
        ("noise burst / blurred frame check", every + " (trust)", lambda f: a._noise(a._work)),
        ("blobs: contours, fill, area, saturation, deformation", every + " with changed pixels", lambda f: a._blobs()),
        ("uniform frame check", "global or photometric change", lambda f: chk.is_uniform(a._thumb_f)),
        ("colour order (RGB) check", "global change, no contact tracked",
         lambda f: chk.colour_swapped(a._y, a._ref.x, a.options.fit_tolerance, a._fit_frac)),
        ("gel/camera motion check", "onset of a change",
         lambda f: chk.motion_explained(a._thumb_f, a._tmodel, a._tr, a._ref)),
        ("motion basis derived again", "first onset after a background refresh", motion_basis),
        ("occlusion (dark share) check", "onset with changed pixels",
         lambda f: chk.dark_share(a._thumb_f, a._ref.dark(), a._tcmp, a._tdark)),
        ("mismatch border check", "background mismatch state", lambda f: chk.borders_changed(a._inl)),
        ("data statistics check (runtime, bundle's data_stats)", "contact readings",
         lambda f: stats.out_of_distribution(a._thumb)),
    ]

    def whole(f):
        exposure_problem(b.reduce(f))
        b.update(f)

    n = warmup + frames
    t = np.full((n, len(stages) + 1), np.nan)
    clock = time.perf_counter_ns
    n_every = sum(1 for st in stages if st[1].startswith(every))
    # Pass 1: the every-frame stages and the whole path, interleaved; pass 2: the checks that
    # run on some frames only, after the every-frame stages of the same frame (untimed), so
    # their memory traffic does not colour the every-frame figures.
    for rare in (False, True):
        for i in range(n):
            fa, fb = pool.rgb[i % len(pool.rgb)], pool.rgb[(i + len(pool.rgb) // 2) % len(pool.rgb)]
            for j, (_, _, fn) in enumerate(stages):
                if rare and j < n_every:
                    fn(fa)
                    continue
                if not rare and j >= n_every:
                    break
                t0 = clock()
                fn(fa)
                t[i, j] = (clock() - t0) / 1e3
            if not rare:
                t0 = clock()
                whole(fb)
                t[i, -1] = (clock() - t0) / 1e3
    t = t[warmup:]
    total = percentiles(t[:, -1])
    rows: list[list[object]] = []
    for j, (label, when, _) in enumerate(stages):
        p = percentiles(t[:, j])
        rows.append([label, when, p.p50, p.p99, f"{100 * p.p50 / total.p50:.0f} %"])
    every_frame = percentiles(t[:, :n_every].sum(1))
    rows.append(["sum of the every-frame stages", every, every_frame.p50, every_frame.p99,
                 f"{100 * every_frame.p50 / total.p50:.0f} %"])
    rows.append(["whole gate path (reduce + exposure check + update)", "every frame (contact frames here)",
                 total.p50, total.p99, "100 %"])
    return rows


def check_runs(runs: int = 10, frames: int = 1000) -> list[list[object]]:
    """The under-1 ms check (benchmarks/check.py: the best RGBmod bundle's total p99 through
    ForceRuntime, one thread, frames in contact) ``runs`` times back to back:
    [[run, bundle, total p50 ms, total p99 ms, verdict, machine]]."""
    from .check import BUDGET_MS, JUDGED, _best
    from .latency import measure
    from .machine import CpuWindow

    rows = []
    for k in range(1, runs + 1):
        w = CpuWindow()
        which, best, _ = _best(measure, frames, BUDGET_MS)
        state = w.stop()
        t = best.stages[JUDGED]
        verdict = "PASS" if t.p99 <= BUDGET_MS else ("NO VERDICT (machine busy)" if state.busy else "FAIL")
        rows.append([k, which, t.p50, t.p99, verdict, state.line()])
    return rows


def graph_rows(runs: int = 400) -> list[list[object]]:
    """Per-op time (us, median per run, onnxruntime profiler) of the reference and default graphs."""
    from .frames import frame_pool
    from .latency_page import node_profile

    pool = frame_pool()
    rows = []
    for label, b in (("reference c1733e6", REFERENCE_GRAPH), ("default (80x60 input)", DEFAULT_DIR)):
        ops, run = node_profile(b, pool, runs)
        rows.append([label, "model_run (profiling on)", run, "", ""])
        rows += [[label, *r] for r in ops]
    return rows


def page(argv: list[str], frames: int = 2000, check: int = 10, quick: bool = False) -> str:
    """docs/benchmarks/one_downscale.md."""
    from .machine import command_line, describe_machine, header
    from .stats import markdown_table

    run = interleaved(frames=frames, warmup=50 if quick else 200)
    gate = gate_rows(300 if quick else 2000, 50 if quick else 200)
    red_rows = reduction_timings(200 if quick else 2000)
    acc = accuracy()
    graph = graph_rows(100 if quick else 400)
    from .graph_profile import measure as graph_variants

    variants = graph_variants(300 if quick else 2000)
    checks = check_runs(check, 200 if quick else 1000)
    machine = describe_machine()
    passed = sum(1 for r in checks if r[4] == "PASS")
    busy = run["machine"].busy or any("BUSY" in str(r[5]) for r in checks)
    warning = ("**Measured on a BUSY machine (other processes used the cores): the p99 figures and the check "
               "verdicts are not the runtime's; regenerate on an idle machine with the command above.**"
               if busy else "")
    parts = [header("One downscale per frame (issue 18)", command_line(argv), machine,
                    "Ratios are to the reference: a bare onnxruntime session (1 intra-op thread, sequential) on "
                    "today's default graph of commit c1733e6 (`benchmarks/reference_graphs/default_c1733e6.onnx`, "
                    "full-resolution uint8 input, 4x4 AveragePool in the graph), timed interleaved frame by frame "
                    "with the runtimes in ONE run, so machine speed cancels. Frames: virtual DIGIT frames in "
                    "contact from memory (`benchmarks/frames.py`). "
                    f"Machine during the interleaved run: {run['machine'].line()}."),
             *([warning, ""] if warning else []),
             "## Goals", "",
             markdown_table(["goal", "limit (x reference p50)", "before (issue, c1733e6)", "before (this run: "
                             "reference graph through today's runtime)", "after (default bundle)", "met"],
                            goal_rows(run)),
             "", "## Stages", "",
             markdown_table(["path", "stage", "p50 ms", "p99 ms", "p50 / reference p50", "frames"], stage_rows(run)),
             "", "## The gate, stage by stage (one thread, us; `python -m benchmarks.one_downscale gate`)", "",
             "Each stage is the gate's own method, timed on every frame (a check that runs only on some frames "
             "shows what it costs when it runs); the last row is the whole path the runtime calls, timed on "
             "another gate in the same loop. Frames in contact, cold in the cache.", "",
             markdown_table(["stage", "runs on", "p50 us", "p99 us", "p50 / whole gate p50"], gate),
             "", "## How the frame is reduced (320x240x3 -> 80x60x3, one thread, interleaved)", "",
             markdown_table(["method", "p50 us", "p99 us", "max |diff| to the exact mean (levels)",
                             "share of pixels off the rounded mean"], red_rows),
             "", "Accuracy of the default weights under each reduction (RE = |f - f_gt| / f_gt; synthetic: the "
                 "reference recipe's held-out test split; real: the 11 labelled AUROVA DIGIT frames):", "",
             markdown_table(["graph", "reduction", "RE synthetic", "MAE synthetic (N)", "RE AUROVA", "MAE AUROVA (N)"],
                            acc),
             "", "## The graph, node by node (onnxruntime profiler, us per run, median)", "",
             markdown_table(["graph", "op", "us", "share", "nodes"], graph),
             "", "Variants of the default graph, timed round-robin in one run (`python -m benchmarks.graph_profile`; "
                 "ratio to the shipped graph with the runtime's session options). Kept: int8, NHWC uint8 input, "
                 "ORT_ENABLE_ALL; the fp32 row's difference includes the int8 graph's activation clipping:", "",
             markdown_table(["variant", "p50 us", "p99 us", "p50 / shipped", "max |diff| N"], variants),
             "", f"## The under-1 ms check, {len(checks)} runs back to back ({passed}/{len(checks)} PASS)", "",
             markdown_table(["run", "bundle", "total p50 ms", "total p99 ms", "verdict", "machine"], checks)]
    return "\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.one_downscale", description=__doc__.split("\n")[0])
    ap.add_argument("what", choices=("make-default", "accuracy", "reductions", "goals", "gate"))
    ap.add_argument("--frames", type=int, default=2000, help="goals: frames per path after warm-up")
    args = ap.parse_args(argv)
    if args.what == "goals":
        from .stats import markdown_table

        run = interleaved(frames=args.frames)
        print(markdown_table(["goal", "limit", "before (issue)", "before (this run)", "after", "met"], goal_rows(run)))
        print(markdown_table(["path", "stage", "p50 ms", "p99 ms", "p50/ref", "n"], stage_rows(run)))
        print(run["machine"].line())
    elif args.what == "gate":
        from .stats import markdown_table

        print(markdown_table(["stage", "runs on", "p50 us", "p99 us", "p50 / whole gate p50"],
                             gate_rows(frames=args.frames)))
    elif args.what == "make-default":
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
