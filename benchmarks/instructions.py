"""Work per reading, in instructions (instructions.md): what a ``ForceRuntime`` reading and the
bare graph's call execute, counted by valgrind's callgrind, per shipped bundle.

Per bundle (edge/models/default = RGBmod, d = D, rgbmod_d = RGBmod+D, fast = RGBmod fast) one worker process
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
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .harness import callgrind
from .harness.paths import repo_root

#: Shipped bundles measured: (folder under edge/models, label).
VARIANTS: tuple[tuple[str, str], ...] = (("default", "RGBmod"), ("d", "D"), ("rgbmod_d", "RGBmod+D"),
                                         ("fast", "RGBmod fast"))
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


# ----------------------------------------------------------------------------- the record
@dataclass
class Count:
    """Instructions per reading / call of one mode: total and per group
    (:data:`~.harness.callgrind.GROUP_NAMES`)."""

    total: float
    groups: dict[str, float]


@dataclass
class VariantCounts:
    """One bundle's counts: mode -> :class:`Count` (runtime, bare, gate, depth where it has
    one) and the ratio runtime / bare."""

    bundle: str
    label: str
    counts: dict[str, Count]
    ratio: float
    #: the per-frame path counted (:data:`PATHS`); records before the robot-side path existed: compiled
    path: str = "compiled"


@dataclass
class Record:
    """instructions.json: what was counted, how, where."""

    command: str
    commit: str
    cpu: str
    machine: str
    readings: int
    frames: int
    warmup: int
    valgrind: str
    variants: list[VariantCounts] = field(default_factory=list)
    seconds: float = 0.0
    before_commit: str = ""
    before: list = field(default_factory=list)  # the before record's variants, as in its JSON
    notes: str = ""  # what the page says besides (e.g. counts carried over from another run)


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


# ----------------------------------------------------------------------------- the page
#: The goals (issue's wording in docs): runtime / bare graph per bundle, at most.
GOALS = {"RGBmod": 1.15, "D": 1.5, "RGBmod+D": 1.25}
#: The fast bundle's goal: its reading / the default's reading, at most.
FAST_GOAL = 0.5


def _m(x: float) -> str:
    return f"{x / 1e6:.3f}"


def stages(v: VariantCounts) -> dict[str, float]:
    """Instructions per reading by stage: runtime, bare, gate, depth, and the rest (glue +
    judge + the model wrapper = runtime - bare - gate - depth); a stage not counted is absent."""
    c = v.counts
    out = {"runtime": c["runtime"].total, "bare": c["bare"].total}
    for k in ("gate", "depth"):
        if k in c:
            out[k] = c[k].total
    if "gate" in c:
        out["glue + judge"] = out["runtime"] - out["bare"] - out["gate"] - out.get("depth", 0.0)
    return out


def _variants(raw: list) -> list[VariantCounts]:
    return [VariantCounts(v["bundle"], v["label"], {k: Count(**c) for k, c in v["counts"].items()}, v["ratio"],
                          v.get("path", "compiled")) for v in raw]


def _paths_section(rec: Record) -> list[str]:
    """Per bundle: the robot-side path's reading against the compiled kernels' (and against the before
    record's, counted on the compiled kernels where it predates the robot-side path)."""
    from .harness.stats import markdown_table

    by = {(v.bundle, v.path): v for v in rec.variants}
    before = {v.bundle: v for v in _variants(rec.before) if v.path == "compiled"} if rec.before else {}
    rows = []
    for name, label in VARIANTS:
        c, o = by.get((name, "compiled")), by.get((name, "opencv"))
        if o is None:
            continue
        oc = o.counts["runtime"].total
        cc = c.counts["runtime"].total if c else None
        b = before.get(name)
        bc = b.counts["runtime"].total if b else None
        rows.append([label, _m(oc), "-" if cc is None else _m(cc),
                     "-" if cc is None else f"{100 * (oc / cc - 1):+.0f} %",
                     "-" if bc is None else _m(bc), "-" if bc is None else f"{100 * (oc / bc - 1):+.0f} %",
                     "-" if cc is None or bc is None else f"{100 * (cc / bc - 1):+.1f} %"])
    if not rows:
        return []
    return ["## The robot-side path against the compiled kernels (M per reading)", "",
            "The robot-side install (`pip install .`) runs the gate's and the depth stage's OpenCV / numpy calls; "
            "the `fast` extra the compiled kernels (edge/compiled_path.py). The readings are the same; the "
            "instructions are not. 'before': the before record's reading (compiled kernels)." if rec.before else
            "The robot-side install (`pip install .`) runs the gate's and the depth stage's OpenCV / numpy calls; "
            "the `fast` extra the compiled kernels (edge/compiled_path.py). The readings are the same.", "",
            markdown_table(["bundle", "robot-side path", "compiled kernels", "robot-side / compiled", "before",
                            "robot-side / before", "compiled / before"], rows), ""]


def _fast_ratio(variants: list[VariantCounts]) -> float | None:
    """The fast bundle's runtime reading / the default's (None unless both were counted)."""
    by = {v.label: v for v in variants}
    if "RGBmod fast" not in by or "RGBmod" not in by:
        return None
    return by["RGBmod fast"].counts["runtime"].total / by["RGBmod"].counts["runtime"].total


def _floors(rec: Record) -> list[str]:
    """The page's floors section: per bundle with a goal, what the goal leaves around the bare call
    against what the reading does there that no exact implementation of today's checks avoids."""
    from .harness.stats import markdown_table

    rows = []
    for v in rec.variants:
        c, st = v.counts, stages(v)
        if v.label not in GOALS or "downscale" not in c or "gate" not in st:
            continue
        budget = (GOALS[v.label] - 1.0) * st["bare"]
        down = c["downscale"].total
        left = budget - down - st["glue + judge"]
        rest = st["gate"] - down + st.get("depth", 0.0)
        cv = f" (OpenCV's x2 steps: {_m(c['downscale_opencv'].total)})" if "downscale_opencv" in c else ""
        rows.append([v.label, f"{GOALS[v.label]:.2f}x", _m(budget), _m(down) + cv, _m(st["glue + judge"]),
                     _m(left), _m(rest), f"{rest / left:.1f}x" if left > 0 else "no room"])
    if not rows:
        return []
    return ["## What a goal leaves for the checks (M per reading)", "",
            "'room around the bare call': (goal - 1) x the bare call. 'the one downscale': the gate's reduction of "
            "the frame alone, which the network's input is, bit for bit (the gate's kernel; OpenCV's INTER_AREA x2 "
            "steps give the same values for the count in brackets). 'left for the checks': the room less the "
            "downscale and the runtime's glue + judge. 'the checks cost': the gate step beyond its downscale (frame "
            "contract, exposure, blur, thumbnail, pixel noise, photometric fit, changed mask, blobs, judging) and the "
            "depth stage. Every check is one compiled pass or OpenCV call per frame; the goal holds only where "
            "'checks / left' is at most 1.", "",
            markdown_table(["bundle", "goal", "room around the bare call", "the one downscale", "glue + judge",
                            "left for the checks", "the checks cost", "checks / left"], rows), ""]


def page(rec: Record) -> str:
    """instructions.md from the record (with before / after tables when it holds a before)."""
    from .harness.stats import markdown_table

    before = {v.label: v for v in _variants(rec.before)} if rec.before else {}
    out = ["# Instructions per reading", "", f"Command: `{rec.command}`", "", f"Commit: {rec.commit}", "",
           f"CPU: {rec.cpu}. Machine: {rec.machine}.", "",
           f"Counted by {rec.valgrind} (callgrind: instructions executed, the same on any load or clock). Per "
           f"shipped bundle, {rec.readings} readings back to back over {rec.frames} virtual DIGIT frames in contact, "
           f"after {rec.warmup} warm-up readings, each stage counted alone in the bundle's one run "
           "(benchmarks/instructions.py). 'runtime': one `ForceRuntime.step` (one sensor, in-memory source, "
           "warm-ups off); 'bare': one `InferenceSession.run` of the bundle's graph (one thread) on the same reduced "
           "inputs; 'gate': the gate step alone (frame contract, exposure, contact gate); 'depth': the depth stage "
           "alone on the gate's reduced image and mask; 'glue + judge': runtime - bare - gate - depth (the "
           "runtime's own work, the judge, the model wrapper). M = millions of instructions per reading.", ""]
    if rec.notes:
        out += [rec.notes, ""]
    if before:
        out += [f"Before: commit {rec.before_commit} (the same command and CPU).", "", "## Goals", ""]
        rows = []
        for v in rec.variants:
            b = before.get(v.label)
            if v.label in GOALS:
                rows.append([f"{v.label}: runtime / bare graph <= {GOALS[v.label]:.2f}x",
                             f"{b.ratio:.2f}x" if b else "-", f"{v.ratio:.2f}x",
                             "met" if v.ratio <= GOALS[v.label] else "NOT met"])
        fast = _fast_ratio(rec.variants)
        if fast is not None:
            b_fast = _fast_ratio(_variants(rec.before))
            rows.append([f"RGBmod fast: its reading / the default's reading <= {FAST_GOAL:.2f}x",
                         f"{b_fast:.2f}x" if b_fast is not None else "-", f"{fast:.2f}x",
                         "met" if fast <= FAST_GOAL else "NOT met"])
        out += [markdown_table(["goal", "before", "after", ""], rows), ""]
    rows = []
    for v in rec.variants:
        st = stages(v)
        rows.append([v.label, _m(st["runtime"]), _m(st["bare"]), f"{v.ratio:.2f}x",
                     *(_m(st[k]) if k in st else "-" for k in ("gate", "depth", "glue + judge"))])
    out += ["## Per reading", "",
            markdown_table(["bundle", "runtime (M)", "bare call (M)", "runtime / bare", "gate (M)", "depth (M)",
                            "glue + judge (M)"], rows), ""]
    if before:
        rows = []
        for v in rec.variants:
            b = before.get(v.label)
            if b is None:
                continue
            sa, sb = stages(v), stages(b)
            for k in sa:
                if k in sb:
                    rows.append([v.label, k, _m(sb[k]), _m(sa[k]), _m(sa[k] - sb[k]),
                                 f"{100 * (sa[k] / sb[k] - 1):+.0f} %" if sb[k] else "-"])
        out += ["## Per stage, before and after (M per reading)", "",
                markdown_table(["bundle", "stage", "before", "after", "change", "change %"], rows), ""]
    out += _paths_section(rec)
    out += _floors(rec)
    groups = callgrind.GROUP_NAMES
    out += ["## Where the instructions ran (M per reading)", "",
            "By object file (OpenCV: cv2 and libopencv*; numpy: its extension modules; the interpreter: "
            "python / libpython; libc memset/memcpy: those functions of the C library, the rest of it apart).", ""]
    rows = []
    for v in rec.variants:
        b = before.get(v.label)
        for mode, cnt in v.counts.items():
            if b is not None and mode in b.counts:
                bc = b.counts[mode]
                rows.append([v.label, f"{mode} (before)", _m(bc.total), *(_m(bc.groups[g]) for g in groups)])
            rows.append([v.label, mode if b is None else f"{mode} (after)", _m(cnt.total),
                         *(_m(cnt.groups[g]) for g in groups)])
    out += [markdown_table(["bundle", "what", "total", *groups], rows), ""]
    out += [f"Each bundle's modes counted in one run, each alone (callgrind's client requests; set-up and "
            f"imports neither instrumented nor counted). Counting took {rec.seconds:.0f} s.", ""]
    return "\n".join(out) + "\n"


def read_before(path: Path) -> tuple[str, list]:
    """(commit, variants as in the JSON) of an earlier instructions.json; ValueError saying what is
    wrong (missing, a folder, not JSON, a key or a variant's field missing or of the wrong type)."""
    path = Path(path)
    if not path.exists():
        raise ValueError("no such file; expected an earlier instructions.json")
    if not path.is_file():
        raise ValueError("not a file; expected an earlier instructions.json")
    try:
        raw = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"not readable as JSON ({exc.__class__.__name__}: {exc})") from None
    if not isinstance(raw, dict) or not isinstance(raw.get("commit"), str) or not isinstance(raw.get("variants"),
                                                                                           list):
        raise ValueError("expected an instructions.json: an object with 'commit' (text) and 'variants' (a list)")
    try:
        parsed = _variants(raw["variants"])
        for v in parsed:
            stages(v)
            float(v.ratio)
            for c in v.counts.values():
                float(c.total)
                {str(k): float(x) for k, x in c.groups.items()}
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise ValueError(f"a variant is not of the shape instructions.json records ({exc.__class__.__name__}: "
                         f"{exc})") from None
    return raw["commit"], raw["variants"]


def run(args: argparse.Namespace, argv: list[str]) -> int:
    """``python -m benchmarks instructions``: count, write instructions.json then .md to ``args.out``."""
    from .harness.machine import command_line, describe_machine
    from .harness.paths import source_commit

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
    callgrind.write_counted(args.out, "instructions", json.dumps(asdict(rec), indent=1) + "\n", page(rec))
    print(f"wrote {args.out / 'instructions.md'}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--worker":
        sys.exit(worker(sys.argv[2:]))
    print("usage: python -m benchmarks instructions [--readings N] [--out DIR]", file=sys.stderr)
    sys.exit(2)
