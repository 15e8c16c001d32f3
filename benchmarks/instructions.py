"""Work per reading, in instructions (instructions.md): what a ``ForceRuntime`` reading and the
bare graph's call execute, counted by valgrind's callgrind, per shipped bundle.

Per bundle (rgbmod_int8 = RGBmod, d = D, rgbmod_d = RGBmod+D, default = RGBmod fast) one worker process
sets up, the same way in every run: virtual DIGIT frames in contact (rendered once, outside
callgrind), a ``ForceRuntime`` over them (one sensor, an in-memory source read back to back,
its gate's background captured from no-contact frames, warm-ups off, OpenCV on one thread as
a scene with ``threads = 1`` runs), a bare onnxruntime
session of the bundle's graph (one thread, sequential, the runtime's session options) fed the
same reduced inputs the runtime hands its model, and the stages alone: the gate step
(``GateStep.run``: the frame contract, the exposure and the contact gate) and, for D and
RGBmod+D, the depth stage on the gate's reduced image and mask. Each of these runs a few
times to warm up; then each runs N times (``--readings``), counted alone: one run under
callgrind with instrumentation off until the worker turns it on around each mode's N calls
(callgrind's client requests, benchmarks/harness/client_requests.py, x86-64; imports, loading
and warm-up are neither instrumented nor counted), so instructions per reading = the mode's
count / N. The counts split by where the instructions ran (the
object files: onnxruntime, OpenCV, numpy, OpenBLAS, libc memset / memcpy, the interpreter,
...), and the stages by running them alone. Instruction counts do not depend on the load or
clock of the host; the CPU model is named because libraries pick code paths by the CPU's
features (AVX2, AVX-512).

    python -m benchmarks instructions --out docs/benchmarks    # -> instructions.md + .json
    python -m benchmarks instructions --quick                  # a smoke run (few readings)

Each bundle is counted on both per-frame paths (edge/compiled_path.py): ``compiled``, the ``fast``
extra's kernels (``TACTILE_FORCE_KERNELS=compile`` in the worker), and ``opencv``, the OpenCV / numpy
calls of the robot-side install (``TACTILE_FORCE_KERNELS=off``); the worker checks that it runs the
path it counts. ``--paths`` picks one.

Where valgrind is not installed, or the host is not x86-64, the command says so and exits 0
without a page.
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import sys
import tempfile
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

from .harness import callgrind
from .harness.paths import repo_root
from .instructions_record import (  # noqa: F401 - the record and page, re-exported as this page's own
    FAST_GOAL,
    GOALS,
    VARIANTS,
    Count,
    Record,
    VariantCounts,
    page,
    read_before,
    stages,
)

#: What a worker run counts, each mode N times ('downscale': the gate's one downscale of the frame alone,
#: the network's input, by the gate's kernel; 'downscale_opencv': the same values by OpenCV's INTER_AREA
#: x2 steps; the floors of the page).
MODES = ("runtime", "bare", "gate", "depth", "downscale", "downscale_opencv")
#: The per-frame paths counted: the fast extra's compiled kernels, and the robot-side install's OpenCV calls
#: (the value of TACTILE_FORCE_KERNELS in the worker).
PATHS = {"compiled": "compile", "opencv": "off"}
#: how a path's rows are labelled beside the bundle's label
PATH_SUFFIX = {"compiled": "", "opencv": " (OpenCV path)"}
FRAMES = 16  # virtual DIGIT frames in contact, cycled
WARMUP = 5  # runs of every mode before the measured ones, in every worker run
READINGS = 200  # measured readings per run (--quick: 20)


def models_dir() -> Path:
    """edge/models of the package."""
    from tactile_force.edge.scene import PACKAGE_DIR

    return Path(PACKAGE_DIR) / "models"


# ----------------------------------------------------------------------------- the worker
class _Setup:
    """Everything a worker run builds (uncounted)."""

    def __init__(self, bundle_dir: Path, frames: Path, readings: int) -> None:
        import onnxruntime as ort
        from tactile_force.edge import ContactGate, load_bundle
        from tactile_force.edge.bundle.manifest import InputKind
        from tactile_force.edge.frames import TimedFrame
        from tactile_force.edge.gate import GateOptions
        from tactile_force.edge.gate.frame_work import FrameWork
        from tactile_force.edge.model.onnx_model import OnnxForceModel, bundle_session_options
        from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
        from tactile_force.edge.runtime.depth_factory import build_depth_stage
        from tactile_force.edge.runtime.gating import GateStep

        from .harness.sources import MemorySource

        z = np.load(frames)
        rgb, background = z["rgb"], z["background"]
        self.tfs = [TimedFrame(f, i, i, arrival_ns=i) for i, f in enumerate(rgb)]
        bundle = load_bundle(bundle_dir)
        manifest = bundle.manifest
        # the runtime: one sensor, read back to back, warm-ups off
        gate = ContactGate()
        gate.capture_background(background)
        model = OnnxForceModel(bundle, threads=1)
        src = MemorySource(rgb, WARMUP + readings)
        self.runtime = ForceRuntime([Sensor("s0", src, gate)], model,
                                    RuntimeOptions(deadline_ms=1e9, prewarm=False))
        # the gate step alone (its own gate), and the gate's reduced images and masks
        self.gate_step = GateStep("gate", _gate(background))
        o = GateOptions()  # the gate's image work (its buffers), for the downscale alone
        self.frame_work = FrameWork(rgb[0].shape, o.downscale, o.blur, o.threshold)
        ref_step = GateStep("ref", _gate(background))
        self.depth = build_depth_stage(None, manifest) if manifest.input(InputKind.DEPTH) is not None else None
        reduced, masks, depth = [], [], []
        for tf in self.tfs:
            g = ref_step.run(tf)
            assert g is not None and g.contact and g.reduced is not None
            reduced.append(g.reduced.copy())
            masks.append(g.reduced_mask.copy())
            if self.depth is not None:
                res = self.depth.process(reduced[-1], masks[-1], checked=True)
                assert res.ok, res.detail
                depth.append(res.depth.copy())
        self.reduced, self.masks = reduced, masks
        # the bare graph: the same reduced inputs the runtime hands its model
        self.sess = ort.InferenceSession(str(bundle.onnx_path), bundle_session_options(bundle, 1),
                                         providers=["CPUExecutionProvider"])
        self.out = [manifest.output.name]
        feeds = []
        for k in range(len(rgb)):
            feed = {}
            for s in manifest.inputs:
                x = depth[k] if s.kind is InputKind.DEPTH else reduced[k]
                feed[s.name] = np.ascontiguousarray(x.reshape(1, *x.shape))
            feeds.append(feed)
        self.feeds = feeds
        self.k = 0

    def once(self, mode: str) -> None:
        """One reading / call of ``mode``."""
        k = self.k % len(self.tfs)
        self.k += 1
        if mode == "runtime":
            self.runtime.step()
        elif mode == "bare":
            self.sess.run(self.out, self.feeds[k])
        elif mode == "gate":
            self.gate_step.run(self.tfs[k])
        elif mode == "depth" and self.depth is not None:
            self.depth.process(self.reduced[k], self.masks[k], checked=True)
        elif mode == "downscale":
            self.frame_work.reduce(self.tfs[k].frame)
        elif mode == "downscale_opencv":
            self.frame_work.reduce_without_kernels(self.tfs[k].frame)


def _gate(background: np.ndarray):
    from tactile_force.edge import ContactGate

    g = ContactGate()
    g.capture_background(background)
    return g


def worker(argv: list[str]) -> int:
    """``python -m benchmarks.instructions --worker BUNDLE FRAMES MODES N``: set up, warm every
    mode up, then run each mode of MODES (comma-separated) N times, each in its own callgrind
    segment (:class:`~.harness.client_requests.Segment`: nothing else is counted)."""
    import cv2

    from .harness.client_requests import Segment, on_valgrind

    # One OpenCV thread, as a scene with threads = 1 runs (edge/scene/build.py): a thread pool's
    # workers spin while they wait, and how long depends on the host's load, not on the code.
    cv2.setNumThreads(1)
    bundle, frames, modes, n = Path(argv[0]), Path(argv[1]), argv[2].split(","), int(argv[3])
    on_valgrind()  # the request compiled before anything is counted
    setup = _Setup(bundle, frames, n if "runtime" in modes else 0)
    from tactile_force.edge import compiled_path

    path = os.environ.get("TACTILE_FORCE_KERNELS", "")
    uses = setup.frame_work._k is not None
    if uses != (path == "compile"):  # never count one path under the other's name
        raise RuntimeError(f"worker: TACTILE_FORCE_KERNELS={path!r} but the gate runs "
                           f"{'the compiled kernels' if uses else 'OpenCV'} ({compiled_path.describe()})")
    for m in MODES:
        for _ in range(WARMUP if m != "runtime" else 0):
            setup.once(m)
    for _ in range(WARMUP):  # the runtime's warm-up readings
        setup.once("runtime")
    for mode in modes:
        gc.collect()
        with Segment(mode):
            for _ in range(n):
                setup.once(mode)
    return 0


def _frames_file(tmp: Path, n: int = FRAMES) -> Path:
    from .harness.frames import contact_frames

    pool = contact_frames(n, seed=0)
    p = tmp / "frames.npz"
    np.savez(p, rgb=pool.rgb, background=pool.background)
    return p


def _env() -> dict[str, str]:
    env = dict(os.environ)
    for v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        env[v] = "1"
    env["PYTHONHASHSEED"] = "0"
    root = repo_root()
    if root is not None:
        env["PYTHONPATH"] = os.pathsep.join(p for p in (str(root), env.get("PYTHONPATH", "")) if p)
    return env


def count_variant(bundle: Path, label: str, frames: Path, readings: int, tmp: Path, log=print,
                  modes: tuple[str, ...] = MODES, path: str = "compiled") -> VariantCounts:
    """Count one bundle's modes of ``modes`` (runtime and bare always; depth only for a bundle with
    a depth input), N = ``readings`` each, in one run on the per-frame ``path`` (:data:`PATHS`): each
    mode in its own segment (:mod:`.harness.client_requests`)."""
    from tactile_force.edge.bundle.manifest import InputKind
    from tactile_force.edge.bundle.store import read_manifest

    has_depth = read_manifest(bundle / "model.json").input(InputKind.DEPTH) is not None
    wanted = {*modes, "runtime", "bare"}
    modes = tuple(m for m in MODES if m in wanted and (m != "depth" or has_depth))
    t = time.monotonic()
    profiles = callgrind.run_segments([sys.executable, "-m", f"{__package__ or 'benchmarks'}.instructions",
                                       "--worker", str(bundle), str(frames), ",".join(modes), str(readings)],
                                      tmp / f"callgrind.{bundle.name}.{path}.out",
                                      {**_env(), "TACTILE_FORCE_KERNELS": PATHS[path]})
    missing = set(modes) - set(profiles)
    if missing:
        raise RuntimeError(f"{label}: no count of {', '.join(sorted(missing))} in the worker's run")
    counts = {m: Count(profiles[m].total / readings, {k: v / readings for k, v in profiles[m].by_group().items()})
              for m in modes}
    label += PATH_SUFFIX[path]
    log(f"  {label} {', '.join(modes)} x{readings}: " + ", ".join(f"{m} {profiles[m].total:,}" for m in modes)
        + f" instructions ({time.monotonic() - t:.0f} s)")
    return VariantCounts(bundle.name, label, counts, counts["runtime"].total / counts["bare"].total, path)


def measure(readings: int, variants: list[str] | None = None, log=print,
            modes: tuple[str, ...] = MODES, paths: tuple[str, ...] = tuple(PATHS)) -> list[VariantCounts]:
    """Counts of the shipped bundles named in ``variants`` (folders; default every bundle of VARIANTS), the
    modes of ``modes`` (runtime and bare always), on each per-frame path of ``paths``."""
    out = []
    with tempfile.TemporaryDirectory(prefix="instructions-") as d:
        tmp = Path(d)
        frames = _frames_file(tmp)
        for path in paths:
            for name, label in VARIANTS:
                if variants is None or name in variants:
                    out.append(count_variant(models_dir() / name, label, frames, readings, tmp, log, modes, path))
    return out


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """``python -m benchmarks instructions``: count, write instructions.json then .md to ``args.out``."""
    from .harness.machine import command_line, describe_machine
    from .harness.paths import source_commit, write_record_and_page

    why = callgrind.unavailable("instructions")
    if why:
        print(why, file=sys.stderr)
        return 0
    readings = args.readings if args.readings else (20 if args.quick else READINGS)
    before_commit, before = "", []
    if args.before is not None:  # read first: it may be the page being replaced
        before_commit, before = read_before(args.before)
    t0 = time.monotonic()
    variants = measure(readings, args.variants or None, paths=tuple(args.paths or PATHS))
    m = describe_machine()
    vg = callgrind.version()
    rec = Record(command_line(argv), source_commit(), m.cpu, m.line(), readings, FRAMES, WARMUP, vg, variants,
                 time.monotonic() - t0, before_commit, before)
    write_record_and_page(args.out, "instructions", json.dumps(asdict(rec), indent=1) + "\n", page(rec))
    print(f"wrote {args.out / 'instructions.md'}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        sys.exit(worker(sys.argv[2:]))
    print("usage: python -m benchmarks instructions [--readings N] [--out DIR]", file=sys.stderr)
    sys.exit(2)
