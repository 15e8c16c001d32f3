"""Issue 18's floors: the least a gate and a runtime can cost on this host, measured.

    python -m benchmarks.floors --out docs/benchmarks/floors.md

Issue 18 asks, as ratios to the reference (a bare onnxruntime session on the c1733e6 default
graph, full-resolution input), for a gate p50 <= 0.12 and a runtime total p50 <= 0.80. This
page measures, in ONE interleaved run with that reference (one thread, frames in contact from
the same memory pool as the goal run, docs/benchmarks/one_downscale.md), the pieces no
implementation of the issue's design can avoid:

- the one downscale alone (edge/gate/reduce.py, the exact 4x4 box average the model's input is);
- a check-less gate: that downscale, |reduced - background| per channel, a threshold and a
  pixel count, i.e. the least any gate that decides contact from a difference with a
  background computes (no blur, no photometric fit, no blobs, no judging check);
- the shipped gate as the runtime calls it (``ContactGate.reduce`` + ``update``);
- the network alone: a bare onnxruntime session on the shipped default graph (80 x 60 input),
  and the same ResNet-18 topology at width 1/8 (random weights, int8 like the default; needs
  torch to export, else the row says so), which shows how much of the network's time is per
  node rather than per multiply;
- ``ForceRuntime`` with the default bundle: its total and its glue (total - gate - inference).

Each measurement of a frame reads a different frame of the pool (stage s reads frame
i + 8 s), so none of them finds its frame already in the cache because another read it.
From these: the gate floor (check-less gate / reference) and the total floor (network bare +
runtime glue + check-less gate, / reference) against the goals. The page also counts the
OpenCV calls the shipped gate makes on a contact frame (every one costs at least the
``countNonZero`` floor timed here) and times a few of them on 80 x 60 x 3.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import cv2
import numpy as np

REPO = Path(__file__).resolve().parents[1]
REFERENCE_GRAPH = REPO / "benchmarks" / "reference_graphs" / "default_c1733e6.onnx"
DEFAULT_DIR = REPO / "edge" / "models" / "default"
#: Issue 18's limits (x reference p50).
GATE_GOAL, TOTAL_GOAL = 0.12, 0.80
#: Frame offset between the measurements of one iteration (see the module docstring).
STRIDE = 8


class CheckLessGate:
    """The least a difference gate computes per frame: the one downscale, |reduced -
    background| per channel, a threshold (max over B, G, R above ``threshold`` <=> not all
    channels within [0, threshold]) and a pixel count. Buffers allocated once.

    Parameters
    ----------
    background
        Background image at the reduced resolution, H x W x 3 uint8 BGR.
    frame_shape
        (H, W, 3) of the full-resolution frames.
    threshold
        Grey levels above which a pixel counts as changed.
    """

    def __init__(self, background: np.ndarray, frame_shape: tuple[int, int, int], threshold: float = 10.0) -> None:
        from tactile_force.edge.gate.reduce import FrameReducer, default_reduction

        factor = frame_shape[0] // background.shape[0]
        self.reducer = FrameReducer(default_reduction(factor), frame_shape)
        if self.reducer.out_shape != background.shape:
            raise ValueError(f"background {background.shape}: expected {self.reducer.out_shape} (the reduced frame)")
        self.background = np.ascontiguousarray(background)
        self.small = np.empty(self.reducer.out_shape, np.uint8)
        self.diff = np.empty_like(self.small)
        self.inside = np.empty(self.small.shape[:2], np.uint8)
        self.low = np.zeros(3, np.float64)
        self.high = np.full(3, float(threshold), np.float64)

    def __call__(self, frame: np.ndarray) -> int:
        """Changed pixels of ``frame`` (H x W x 3 uint8 BGR) at the reduced resolution."""
        self.reducer(frame, out=self.small)
        cv2.absdiff(self.small, self.background, dst=self.diff)
        cv2.inRange(self.diff, self.low, self.high, dst=self.inside)
        return self.inside.size - cv2.countNonZero(self.inside)


@contextmanager
def counting_opencv() -> Iterator[Counter]:
    """Count calls of OpenCV's functions (by name) made while the block runs; the module's
    attributes are restored afterwards."""
    counts: Counter = Counter()
    saved: dict[str, Callable] = {}
    for name in dir(cv2):
        fn = getattr(cv2, name)
        if type(fn).__name__ == "builtin_function_or_method":
            saved[name] = fn

            def wrapper(*a, _fn=fn, _name=name, **k):
                counts[_name] += 1
                return _fn(*a, **k)

            setattr(cv2, name, wrapper)
    try:
        yield counts
    finally:
        for name, fn in saved.items():
            setattr(cv2, name, fn)


def gate_opencv_calls(pool, frames: int = 16) -> Counter:
    """OpenCV calls per frame (mean, by name) of the shipped gate's per-frame path on frames
    in contact (the background captured first, outside the count)."""
    from tactile_force.edge import ContactGate

    gate = ContactGate()
    gate.capture_background(pool.background)
    for f in pool.rgb[:4]:  # past the first onset
        gate.reduce(f)
        gate.update(f)
    with counting_opencv() as counts:
        for f in pool.rgb[4:4 + frames]:
            gate.reduce(f)
            gate.update(f)
    return Counter({k: v / frames for k, v in counts.items()})


def call_costs(repeats: int = 20000) -> list[tuple[str, float]]:
    """[(call, p50 us)] of single OpenCV calls on 80 x 60 (x 3) uint8 images, one thread."""
    from .stats import percentiles

    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (80, 60, 3), dtype=np.uint8)
    b = rng.integers(0, 256, (80, 60, 3), dtype=np.uint8)
    out = np.empty_like(a)
    m = (rng.random((80, 60)) > 0.5).astype(np.uint8) * 255
    calls = {"cv2.countNonZero (80x60)": lambda: cv2.countNonZero(m),
             "cv2.absdiff (80x60x3)": lambda: cv2.absdiff(a, b, dst=out),
             "cv2.mean (80x60x3)": lambda: cv2.mean(a),
             "cv2.GaussianBlur 3x3 (80x60x3)": lambda: cv2.GaussianBlur(a, (3, 3), 0, dst=out),
             "cv2.findContours (80x60, one blob)": lambda: cv2.findContours(_disc(), cv2.RETR_EXTERNAL,
                                                                            cv2.CHAIN_APPROX_SIMPLE)}
    times: dict[str, list[float]] = {k: [] for k in calls}
    for _ in range(repeats):
        for k, fn in calls.items():
            t0 = time.perf_counter_ns()
            fn()
            times[k].append((time.perf_counter_ns() - t0) / 1e3)
    return [(k, percentiles(v).p50) for k, v in times.items()]


_DISC = np.zeros((80, 60), np.uint8)
cv2.circle(_DISC, (30, 40), 15, 255, -1)


def _disc() -> np.ndarray:
    return _DISC


def width_eighth_graph(dest: Path) -> Path | str:
    """The default's topology at width 1/8 (random weights, int8 static, 80 x 60 input) as a
    bundle in ``dest``; a string saying why not when torch (the export extra) is absent."""
    try:
        import torch
    except ImportError:
        return "needs torch (pip install .[export])"
    import logging
    import warnings

    from tactile_force.edge import load_bundle
    from tactile_force.export import (
        ExportOptions,
        QuantizeOptions,
        build_model,
        export_bundle,
        quantize_bundle,
        random_frames,
    )

    torch.manual_seed(0)
    width = 0.125
    scale = load_bundle(DEFAULT_DIR).manifest.architecture.input_scale
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        logging.disable(logging.WARNING)
        try:
            fp = export_bundle(build_model("rgbmod", width=width).eval(), dest / "fp32",
                               ExportOptions(variant="rgbmod", width=width, input_scale=scale))
            q = quantize_bundle(fp, dest / "int8", QuantizeOptions(), calibration=random_frames("rgbmod", n=16))
        finally:
            logging.disable(logging.NOTSET)
    return Path(q.path)


def _session(path: Path):
    """(bare session, its input name) for the graph at ``path``."""
    from .graph_profile import bare_session

    s = bare_session(path)
    return s, s.get_inputs()[0].name


def numba_shrink() -> Callable[[np.ndarray, np.ndarray], None] | None:
    """The shipped reduction (area-2x-steps x4, the same values) as a numba kernel: the
    compiled-kernel experiment of the page. None when numba is not installed (it is not a
    dependency of the package)."""
    try:
        import numba
    except ImportError:
        return None

    @numba.njit(cache=False, nogil=True, boundscheck=False)
    def kernel(src: np.ndarray, dst: np.ndarray, acc: np.ndarray) -> None:  # pragma: no cover - compiled
        for i in range(dst.shape[0]):
            r0, r1, r2, r3 = src[4 * i], src[4 * i + 1], src[4 * i + 2], src[4 * i + 3]
            for q in range(src.shape[1] // 6):
                for c in range(3):
                    a = 6 * q + c
                    acc[0, 3 * q + c] = (np.uint16(r0[a]) + r0[a + 3] + r1[a] + r1[a + 3] + 2) >> 2
                    acc[1, 3 * q + c] = (np.uint16(r2[a]) + r2[a + 3] + r3[a] + r3[a + 3] + 2) >> 2
            d = dst[i]
            for q in range(dst.shape[1] // 3):
                for c in range(3):
                    a = 6 * q + c
                    d[3 * q + c] = (acc[0, a] + acc[0, a + 3] + acc[1, a] + acc[1, a + 3] + 2) >> 2

    scratch: dict[tuple[int, ...], np.ndarray] = {}

    def shrink(frame: np.ndarray, out: np.ndarray) -> None:
        h, w = frame.shape[:2]
        acc = scratch.setdefault(frame.shape, np.empty((2, w * 3 // 2), np.uint16))
        kernel(frame.reshape(h, w * 3), out.reshape(out.shape[0], -1), acc)

    return shrink


def floor_run(pool, frames: int = 2000, warmup: int = 200, eighth: Path | str | None = None) -> dict:
    """One interleaved run over ``pool`` (benchmarks.frames.FramePool; see the module
    docstring). Returns {name: samples in us, ..., 'machine': MachineState}."""
    from tactile_force.edge import ContactGate, GateOptions, OnnxForceModel
    from tactile_force.edge.reading import Flags
    from tactile_force.edge.runtime.loop import ForceRuntime, RuntimeOptions, Sensor

    from .latency import MemorySource
    from .machine import CpuWindow

    cv2.setNumThreads(1)
    n, p = warmup + frames, len(pool.rgb)
    gate = ContactGate()
    gate.capture_background(pool.background)
    bg_small = gate.reduce(pool.background[0]).copy()
    checkless = CheckLessGate(bg_small, pool.rgb[0].shape)
    plain = ContactGate(GateOptions(trust=False))  # no judging check: difference, fit, blobs
    plain.capture_background(pool.background)
    ref_sess, ref_in = _session(REFERENCE_GRAPH)
    net_sess, net_in = _session(DEFAULT_DIR / "model.onnx")
    small = [gate.reduce(f)[None].copy() for f in pool.rgb]
    eighth_sess = _session(eighth / "model.onnx") if isinstance(eighth, Path) else None
    rt_gate = ContactGate()
    rt_gate.capture_background(pool.background)
    runtime = ForceRuntime([Sensor("floor", MemorySource(pool.rgb, n), rt_gate)], OnnxForceModel(DEFAULT_DIR),
                           RuntimeOptions(threads=1, deadline_ms=1e9, latency_window=16, grabbers=False))
    keys = ["reference bare", "read frame", "shrink", "shrink nearest", "numba shrink", "check-less gate",
            "gate reduce", "gate checks", "gate plain", "shipped gate", "network bare", "network 1/8 bare",
            "runtime total", "runtime gate", "runtime glue"]
    out = {k: np.full(n, np.nan) for k in keys}
    shrink_out = np.empty_like(bg_small)
    copy_out = np.empty_like(pool.rgb[0])
    compiled = numba_shrink()

    def timed(key: str, i: int, fn: Callable[..., object], *args: object) -> None:
        t0 = time.perf_counter_ns()
        fn(*args)
        out[key][i] = (time.perf_counter_ns() - t0) / 1e3

    window = CpuWindow()
    for i in range(n):
        f = [pool.rgb[(i + STRIDE * s) % p] for s in range(8)]
        timed("reference bare", i, ref_sess.run, None, {ref_in: f[0][None]})
        timed("read frame", i, np.copyto, copy_out, f[1])
        timed("shrink", i, checkless.reducer, f[2], shrink_out)
        timed("shrink nearest", i, cv2.resize, f[3], shrink_out.shape[1::-1], shrink_out, 0, 0, cv2.INTER_NEAREST)
        if compiled is not None:
            timed("numba shrink", i, compiled, f[4], shrink_out)
        timed("check-less gate", i, checkless, f[5])
        timed("gate reduce", i, gate.reduce, f[6])
        timed("gate checks", i, gate.update, f[6])
        plain.reduce(f[6])
        timed("gate plain", i, plain.update, f[6])
        out["shipped gate"][i] = out["gate reduce"][i] + out["gate checks"][i]
        timed("network bare", i, net_sess.run, None, {net_in: small[(i + STRIDE * 7) % p]})
        if eighth_sess is not None:
            timed("network 1/8 bare", i, eighth_sess[0].run, None, {eighth_sess[1]: small[(i + STRIDE * 7) % p]})
        for r in runtime.step():
            if r.frame_index >= 0 and not r.flags & (Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.STALE):
                L = r.latency
                out["runtime total"][i] = L.total_ms * 1e3
                out["runtime gate"][i] = L.gate_ms * 1e3
                out["runtime glue"][i] = (L.total_ms - L.gate_ms - L.inference_ms) * 1e3
    state = window.stop()
    runtime.close()
    return {**{k: v[warmup:] for k, v in out.items()}, "machine": state}


def floor_rows(run: dict) -> tuple[list[list[object]], list[list[object]]]:
    """(measurement rows [[what, p50 us, p99 us, p50 / reference p50]], goal rows [[goal,
    limit, floor, how the floor is made, shipped (this run), floor below the limit]])."""
    from .stats import percentiles

    p = {k: percentiles(v) for k, v in run.items() if k != "machine"}
    ref = p["reference bare"].p50
    labels = {"reference bare": "reference: bare session, c1733e6 graph, full-resolution input",
              "read frame": "reading the frame at all: one copy of 320x240x3 into a buffer",
              "shrink": "the one downscale (edge/gate/reduce.py, area-2x-steps x4: two OpenCV 2x2 box averages)",
              "shrink nearest": "a point sample instead: cv2.resize INTER_NEAREST x4 (not a box average)",
              "numba shrink": "area-2x-steps as a numba kernel (same values; experiment, not a dependency)",
              "check-less gate": "check-less gate: downscale + absdiff + threshold + count",
              "gate reduce": "shipped gate: ContactGate.reduce (the one downscale)",
              "gate checks": "shipped gate: ContactGate.update (every check, after the downscale)",
              "gate plain": "ContactGate.update with trust off (no judging check: fit, difference, blobs)",
              "shipped gate": "shipped gate: reduce + update",
              "network bare": "network alone: bare session, shipped default graph (80x60 input)",
              "network 1/8 bare": "same topology at width 1/8 (random weights, int8), bare session",
              "runtime total": "ForceRuntime total, default bundle",
              "runtime gate": "ForceRuntime gate stage",
              "runtime glue": "ForceRuntime glue (total - gate - inference)"}
    rows = [[labels[k], v.p50, v.p99, v.p50 / ref] for k, v in p.items() if v.n]

    def r(*keys: str) -> float:
        return sum(p[k].p50 for k in keys) / ref

    def verdict(x: float, limit: float) -> str:
        return "yes" if x <= limit else "NO"

    gate_floor, checks_floor = r("check-less gate"), r("shrink nearest", "gate checks")
    total_floor = r("network bare", "runtime glue", "check-less gate")
    goals = [["gate p50", f"<= {GATE_GOAL:.2f}", gate_floor, "check-less gate (no judging check)",
              r("shipped gate"), verdict(gate_floor, GATE_GOAL)],
             ["gate p50", f"<= {GATE_GOAL:.2f}", checks_floor, "point-sampled input + the shipped checks",
              r("shipped gate"), verdict(checks_floor, GATE_GOAL)],
             ["runtime total p50", f"<= {TOTAL_GOAL:.2f}", total_floor,
              "network bare + runtime glue + check-less gate", r("runtime total"), verdict(total_floor, TOTAL_GOAL)]]
    if p["network 1/8 bare"].n:
        f8 = r("network 1/8 bare", "runtime glue", "check-less gate")
        f8c = r("network 1/8 bare", "runtime glue", "shrink nearest", "gate checks")
        goals += [["runtime total p50", f"<= {TOTAL_GOAL:.2f}", f8,
                   "width-1/8 network bare + runtime glue + check-less gate", None, verdict(f8, TOTAL_GOAL)],
                  ["runtime total p50", f"<= {TOTAL_GOAL:.2f}", f8c,
                   "width-1/8 network bare + runtime glue + point-sampled input + the shipped checks", None,
                   verdict(f8c, TOTAL_GOAL)]]
    return rows, goals


def page(argv: list[str], frames: int = 2000) -> str:
    """docs/benchmarks/floors.md."""
    from .frames import frame_pool
    from .machine import describe_machine, header
    from .stats import markdown_table

    pool = frame_pool()
    with tempfile.TemporaryDirectory() as tmp:
        eighth = width_eighth_graph(Path(tmp))
        run = floor_run(pool, frames=frames, eighth=eighth)
    rows, goals = floor_rows(run)
    calls = gate_opencv_calls(pool)
    costs = call_costs()
    call_rows = [[k, v] for k, v in sorted(calls.items(), key=lambda kv: -kv[1])]
    total_calls = sum(calls.values())
    floor_call = min(c for _, c in costs)
    notes = [] if isinstance(eighth, Path) else [f"Width-1/8 rows skipped: {eighth}."]
    compiled = numba_shrink()
    if compiled is None:
        notes.append("numba row skipped: numba is not installed (it is not a dependency; `pip install numba` "
                     "to run the experiment).")
    else:
        frame = pool.rgb[0]
        got = np.empty((frame.shape[0] // 4, frame.shape[1] // 4, 3), np.uint8)
        compiled(frame, got)
        from tactile_force.edge.gate.reduce import default_reduction, reduce_frames

        same = np.array_equal(got, reduce_frames(frame[None], default_reduction(4))[0])
        notes.append(f"The numba kernel gives {'the same values as' if same else 'OTHER values than'} the shipped "
                     "reduction on a pool frame; a plain loop kernel, not hand-vectorised for the interleaved "
                     "B, G, R bytes.")
    busy = ("**Measured on a BUSY machine: regenerate on an idle one with the command above.**"
            if run["machine"].busy else "")
    parts = [header("Floors of issue 18's goals", "python -m benchmarks.floors " + " ".join(argv), describe_machine(),
                    __doc__.split("\n\n", 2)[2].strip()),
             *([busy, ""] if busy else []),
             f"Machine during the interleaved run: {run['machine'].line()}.", "",
             "## The floors against the goals (x reference p50)", "",
             markdown_table(["goal", "limit", "floor", "floor made of", "shipped (this run)", "floor within the limit"],
                            goals),
             "", "## Measurements (one interleaved run, one thread, us)", "",
             markdown_table(["what", "p50 us", "p99 us", "p50 / reference p50"], rows),
             *(["", *notes] if notes else []),
             "", f"## OpenCV calls of the shipped gate per contact frame: {total_calls:.1f}", "",
             f"Each costs at least the cheapest call timed below ({floor_call:.2f} us p50), so the calls alone "
             f"take at least {total_calls * floor_call:.0f} us per frame before any arithmetic.", "",
             markdown_table(["OpenCV function", "calls per frame"], call_rows, digits=2),
             "", markdown_table(["single call, one thread", "p50 us"], [list(c) for c in costs], digits=2)]
    return "\n".join(parts) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.floors", description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=2000, help="interleaved iterations after warm-up (default 2000)")
    ap.add_argument("--out", type=Path, help="write the page to this .md file (default: print it)")
    args = ap.parse_args(argv)
    argv_used = (["--frames", str(args.frames)] if args.frames != 2000 else []) + (
        ["--out", str(args.out)] if args.out else [])
    text = page(argv_used, frames=args.frames)
    if args.out:
        tmp = args.out.with_suffix(".md.tmp")
        tmp.write_text(text)
        tmp.replace(args.out)
        print(f"wrote {args.out}")
    else:
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
