"""Issue 19's measured cases, re-runnable: a shared model, another sensor, a pressed background.

    python -m benchmarks.honesty_checks                       # -> out/benchmarks/honesty_checks.md
    python -m benchmarks.honesty_checks --out docs/benchmarks # into the docs (only when asked)
    python -m benchmarks.honesty_checks --quick               # fewer repetitions (smoke run)

1. One OnnxForceModel (the default bundle) shared by two ForceRuntimes stepped in two threads
   on the AUROVA grasp (forwards / backwards), compared reading by reading with one model per
   runtime; the same run with the model's lock bypassed (what c1733e6 did) for comparison;
   and the lock's uncontended cost per predict, interleaved A/B in one process.
2. A compressed student (tiny teacher, 1 epoch, 40 virtual DIGIT frames) run on the GelSight
   Wedge frames at 11-14 N (each grasp's frame 0 as background): its flags.
3. The default bundle calibrated on the AUROVA grasp (``--background`` the unit's no-contact
   image) run on the virtual DIGIT: the contact readings and their flags.
4. The AUROVA 11.88 N frame given as the background of the calibrated bundle: the readings
   that would have been a silent "no contact, 0 N".

Needs ../shared/data (or $TACTILE_FORCE_SHARED_DATA) and, for case 2, the 'export' extra.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import tempfile
import threading
import time
from collections import Counter
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from .machine import describe_machine, header
from .trust import DATA, wedge_grasps

REPO = Path(__file__).resolve().parents[1]
HOME = "aurova_background_b.png"


class _List:
    """Frames as a source (FrameSource protocol: read() -> TimedFrame | None, close())."""

    def __init__(self, frames, truth=None) -> None:
        self.frames, self.truth, self.i = list(frames), truth, 0

    def read(self):
        from tactile_force.edge import TimedFrame

        if self.i >= len(self.frames):
            return None
        f = self.frames[self.i]
        self.i += 1
        if hasattr(f, "frame"):
            return f
        return TimedFrame(f, 0, self.i - 1, None if self.truth is None else self.truth[self.i - 1])

    def close(self) -> None:
        pass


def _aurova() -> tuple[list[np.ndarray], list[float]]:
    from tactile_force.edge.data.dataset import AuthorsDataset

    ds = AuthorsDataset(DATA / "aurova_digit_grasp")
    return [s.frame for s in ds], [float(s.force_n) for s in ds]


def _runtime(model, frames, name, background=None, truth=None):
    from tactile_force.edge import ContactGate, ForceRuntime, RuntimeOptions, Sensor

    gate = ContactGate()
    if background is not None:
        gate.capture_background([background], origin="given background")
    return ForceRuntime([Sensor(name, _List(frames, truth), gate)], model, RuntimeOptions(deadline_ms=1e9))


def _forces(rt) -> list[float]:
    out: list = []
    rt.run(on_reading=out.append)
    return [r.force_n for r in out]


def _flag_counts(readings) -> str:
    from tactile_force.edge import Flags

    c: Counter = Counter()
    for r in readings:
        c["|".join(str(f.name).lower() for f in Flags if f and f in r.flags) or "none"] += 1
    return ", ".join(f"{k}: {v}" for k, v in sorted(c.items()))


# -- 1 ---------------------------------------------------------------------------------------
def shared_model(reps: int) -> tuple[list[str], dict]:
    from tactile_force.edge import OnnxForceModel
    from tactile_force.edge.scene import default_bundle_path

    frames, _ = _aurova()
    bg = cv2.imread(str(DATA / "digit_backgrounds" / HOME))
    seqs = [frames * reps, frames[::-1] * reps]
    solo = [_forces(_runtime(OnnxForceModel(default_bundle_path()), s, "solo", bg)) for s in seqs]
    res = {}
    for label, bypass in (("with the lock (this package)", False), ("lock bypassed (as in c1733e6)", True)):
        shared: Any = OnnxForceModel(default_bundle_path())
        if bypass:
            shared._lock = contextlib.nullcontext()
        rts = [_runtime(shared, s, f"r{k}", bg) for k, s in enumerate(seqs)]
        got: list[list[float]] = [[], []]
        barrier = threading.Barrier(2)

        def work(k: int, rts=rts, got=got, barrier=barrier) -> None:
            barrier.wait()
            got[k] = _forces(rts[k])

        old = sys.getswitchinterval()
        sys.setswitchinterval(1e-5)
        try:
            ts = [threading.Thread(target=work, args=(k,)) for k in range(2)]
            for t in ts:
                t.start()
            for t in ts:
                t.join()
        finally:
            sys.setswitchinterval(old)
        n = sum(len(g) for g in got)
        wrong = sum(1 for g, s in zip(got, solo) for a, b in zip(g, s)
                    if not (math.isnan(a) and math.isnan(b)) and abs(a - b) > 0.01)
        res[label] = (wrong, n)
    # The lock's cost: predict (lock) vs _predict (no lock), interleaved blocks, one thread.
    m: Any = OnnxForceModel(default_bundle_path())
    x = frames[-1][None]
    lock: Any = m._lock
    none: Any = contextlib.nullcontext()
    a_ns: list[float] = []
    b_ns: list[float] = []
    blocks = 20 if reps > 5 else 6
    for _ in range(blocks):
        for guard, acc in ((lock, a_ns), (none, b_ns)):
            m._lock = guard
            t0 = time.perf_counter_ns()
            for _ in range(200):
                m.predict(x, None)
            acc.append((time.perf_counter_ns() - t0) / 200)
    m._lock = lock
    lock_us = (float(np.median(a_ns)) - float(np.median(b_ns))) / 1e3
    bare_a: list[float] = []
    bare_b: list[float] = []  # the lock alone: acquire + release vs an empty context, interleaved
    for _ in range(20):
        for guard, acc in ((lock, bare_a), (none, bare_b)):
            t0 = time.perf_counter_ns()
            for _ in range(100_000):
                with guard:
                    pass
            acc.append((time.perf_counter_ns() - t0) / 100_000)
    bare_ns = float(np.median(bare_a)) - float(np.median(bare_b))
    lines = ["## 1. One model shared by two runtimes in two threads", "",
             "The default bundle; two ForceRuntimes stepped in two threads on the AUROVA grasp (forwards and "
             f"backwards, x{reps}), each reading compared with one model per runtime (|diff| > 0.01 N = wrong).", "",
             "| model use | readings | differing from one model per runtime |", "|---|---|---|"]
    lines += [f"| {k} | {n} | {w} |" for k, (w, n) in res.items()]
    lines += ["", f"Lock cost, uncontended, interleaved A/B in one process ({blocks} x 200 batch-1 predicts each): "
              f"median {np.median(a_ns) / 1e3:.1f} us with the lock vs {np.median(b_ns) / 1e3:.1f} us without, "
              f"difference {lock_us:+.2f} us per call: not measurable against the predict's own run-to-run spread. "
              f"The lock alone (20 x 100000 uncontended `with lock` vs an empty context, interleaved): "
              f"{bare_ns:+.0f} ns per call.", ""]
    return lines, {"shared": res, "lock_us": lock_us, "lock_bare_ns": bare_ns}


# -- 2 ---------------------------------------------------------------------------------------
def compressed_on_wedge(tmp: Path) -> tuple[list[str], dict]:
    from tactile_force.edge import AuthorsDataset, Flags, OnnxForceModel
    from tactile_force.edge.synthetic import DatasetOptions, generate_dataset
    from tactile_force.export import ModelSpec, save_checkpoint
    from tactile_force.export.compress import CompressOptions, Rung, compress_model
    from tactile_force.export.training import Frames, TrainOptions, train_network

    unl = generate_dataset(tmp / "unl", DatasetOptions(n=40, seed=31, progress=False)).root
    teach = generate_dataset(tmp / "teach", DatasetOptions(n=48, seed=32, progress=False)).root
    ds = AuthorsDataset(teach)
    f = Frames({"rgb": np.stack([ds.load(n).frame for n in ds.ids])}, ds.forces().astype(np.float32))
    spec = ModelSpec("rgbmod", 0.125, 1 / 8)
    teacher = save_checkpoint(tmp / "teacher.pth", train_network(spec, f, f, TrainOptions(epochs=1, batch=16,
                                                                                          seed=0)).model, spec)
    res = compress_model(CompressOptions(teacher=teacher, frames=[Path(unl) / "images"], out=tmp / "c",
                                         ladder=(Rung(0.125, 8),), epochs=1, budget_ms=1e6, latency_runs=20,
                                         calibration_frames=20, max_vs_teacher_re=math.inf))
    assert res.bundle is not None
    model = OnnxForceModel(res.bundle.path)
    readings: list = []
    for _, frames, forces in wedge_grasps():
        sel = [k for k, x in enumerate(forces) if 11.0 <= x <= 14.0]
        if sel:
            rt = _runtime(model, [frames[k] for k in sel], "wedge", frames[0], [forces[k] for k in sel])
            rt.run(on_reading=readings.append)
    ood = sum(1 for r in readings if r.flags & Flags.OUT_OF_DISTRIBUTION)
    finite = [r.force_n for r in readings if math.isfinite(r.force_n)]
    ds_ = res.bundle.manifest.data_stats
    lines = ["## 2. A compressed student on GelSight Wedge frames", "",
             f"Student {res.chosen['name'] if res.chosen else '?'} (1 epoch, 40 virtual DIGIT frames; data_stats of "
             f"{ds_.frames if ds_ else 0} frames recorded by compress); the Wedge frames at 11-14 N, each grasp's "
             "frame 0 as background.", "",
             f"- readings: {len(readings)}; flagged out_of_distribution: {ood}; flags: {_flag_counts(readings)}",
             f"- force read: median {np.median(finite) if finite else float('nan'):.2f} N for 11-14 N true", ""]
    return lines, {"wedge_readings": len(readings), "wedge_ood": ood}


# -- 3 and 4 ---------------------------------------------------------------------------------
def calibrated_bundle(tmp: Path) -> Path:
    from tactile_force.edge.fitting.calibrate import calibrate_bundle
    from tactile_force.edge.scene import default_bundle_path

    out = tmp / "calibrated"
    calibrate_bundle(default_bundle_path(), DATA / "aurova_digit_grasp", out,
                     background=DATA / "digit_backgrounds" / HOME)
    return out


def calibrated_on_virtual(cal: Path, n: int) -> tuple[list[str], dict]:
    from tactile_force.edge import Flags, OnnxForceModel
    from tactile_force.edge.synthetic import VirtualDigitSource

    src = VirtualDigitSource(seed=3, n_grasps=6, peak_n=(2.0, 14.0))
    frames: list = []
    while len(frames) < n and (tf := src.read()) is not None:
        frames.append(tf)
    readings: list = []
    rt = _runtime(OnnxForceModel(cal), frames, "virtual")
    rt.run(on_reading=readings.append)
    contact = [r for r in readings if math.isfinite(r.force_n) and Flags.NO_CONTACT not in r.flags]
    flagged = sum(1 for r in contact if Flags.OUT_OF_DISTRIBUTION in r.flags)
    pairs = [(r.force_n, r.truth_n) for r in contact if r.truth_n and r.truth_n >= 1.0]
    re = float(np.mean([abs(a - b) / b for a, b in pairs])) if pairs else float("nan")
    detail = next((r.detail for r in contact if r.detail), "")
    lines = ["## 3. A bundle calibrated on the AUROVA DIGIT, run on the virtual DIGIT", "",
             "calibrate-force on the 11 AUROVA presses with --background aurova_background_b.png (the unit's "
             f"no-contact image), then {len(readings)} virtual DIGIT frames (seed 3) through ForceRuntime.", "",
             f"- contact readings: {len(contact)}; flagged out_of_distribution: {flagged}; RE vs truth {re:.3f}",
             f"- detail: \"{detail}\"", ""]
    return lines, {"virtual_contact": len(contact), "virtual_flagged": flagged}


def pressed_background(cal: Path) -> tuple[list[str], dict]:
    from tactile_force.edge import Flags, OnnxForceModel

    frames, truth = _aurova()
    press = frames[int(np.argmax(truth))]
    readings: list = []
    rt = _runtime(OnnxForceModel(cal), frames, "left", press, truth)
    rt.run(on_reading=readings.append)
    silent = [r for r in readings if r.truth_n and r.truth_n > 1 and Flags.NO_CONTACT in r.flags
              and not r.flags & (Flags.BACKGROUND_MISMATCH | Flags.INVALID_INPUT) and r.force_n == 0.0]
    lines = ["## 4. A pressed frame given as the background", "",
             f"The AUROVA {max(truth):.2f} N frame as the calibrated bundle's background, the 11 presses as frames.",
             "", f"- silent \"no contact, 0 N\" while pressed: {len(silent)}; flags: {_flag_counts(readings)}", ""]
    return lines, {"pressed_silent": len(silent)}


def run(out: Path, quick: bool = False) -> Path:
    machine = describe_machine()
    cmd = "python -m benchmarks.honesty_checks" + (" --quick" if quick else "")
    if out.resolve() != (REPO / "out" / "benchmarks").resolve():
        cmd += f" --out {out}"
    lines = [header("Honesty checks of issue 19: shared models, bundles' data, another sensor, pressed backgrounds",
                    cmd, machine,
                    "Counts, not timings (the lock's cost is an interleaved A/B ratio in one process).")]
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        for part in (lambda: shared_model(5 if quick else 25), lambda: compressed_on_wedge(tmp)):
            text, _ = part()
            lines += text
        cal = calibrated_bundle(tmp)
        lines += calibrated_on_virtual(cal, 200 if quick else 400)[0]
        lines += pressed_background(cal)[0]
    out.mkdir(parents=True, exist_ok=True)
    page = out / "honesty_checks.md"
    page.write_text("\n".join(lines).rstrip() + "\n")
    print(f"wrote {page}")
    return page


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.honesty_checks", description=__doc__.split("\n\n")[0])
    p.add_argument("--out", type=Path, default=REPO / "out" / "benchmarks")
    p.add_argument("--quick", action="store_true")
    a = p.parse_args(argv)
    print(run(a.out, a.quick).read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
