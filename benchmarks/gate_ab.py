"""Interleaved A/B of the contact gate: the ContactGate of an older commit (``git show
REV:edge/gate/contact_gate.py``, loaded beside the current package) against the current one, on the same
frames in one process (frame by frame, the order alternating), after checking that every
GateResult field is bit-identical (given and live-learnt backgrounds, contact, brightness
step, moved gel, RGB order, uniform, noise, occlusion, a re-learnt background).

    python -m benchmarks.gate_ab REV [REPEATS]     # e.g. python -m benchmarks.gate_ab 36479ea 40

Prints the per-frame p50 of each and the new/old ratio (issue 22: within noise, <= 1.03).
Needs a git checkout (the old source is read with ``git show``).
"""

from __future__ import annotations

import logging
import statistics
import subprocess
import sys
import time
import types

import cv2
import numpy as np


def old_gate_module(rev: str) -> types.ModuleType:
    """edge/gate/contact_gate.py as it was at ``rev``, importable beside the current package."""
    src = subprocess.run(["git", "show", f"{rev}:edge/gate.py"], capture_output=True, text=True,
                         check=True).stdout
    src = src.replace("from .", "from tactile_force.edge.")
    mod = types.ModuleType("old_gate")
    mod.__file__ = f"<{rev}:edge/gate/contact_gate.py>"
    sys.modules["old_gate"] = mod
    exec(compile(src, mod.__file__, "exec"), mod.__dict__)  # noqa: S102 - the repository's own source
    return mod


def sequence(background: np.ndarray, rgb: np.ndarray) -> list[np.ndarray]:
    """Contact frames between no-contact ones, with every kind of frame the gate judges."""
    bg = background
    rng = np.random.default_rng(0)
    step = np.clip(bg.astype(np.int16) + 25, 0, 255).astype(np.uint8)
    seq: list[np.ndarray] = []
    for i, f in enumerate(rgb):
        seq += [bg, f]
        if i % 8 == 1:
            seq.append(step)  # brightness step
        if i % 8 == 2:
            seq.append(np.roll(bg, 6, axis=1))  # moved gel
        if i % 8 == 3:
            seq.append(np.ascontiguousarray(bg[..., ::-1]))  # RGB order
        if i % 8 == 4:
            seq.append(np.full_like(bg, 90))  # uniform
        if i % 8 == 5:
            seq.append(np.clip(bg + rng.normal(0, 25, bg.shape), 0, 255).astype(np.uint8))  # noise
        if i % 8 == 6:
            o = bg.copy()
            o[:120] = 5
            seq.append(o)  # occlusion
    seq += [np.roll(bg, 6, axis=1)] * 40 + [bg] * 10  # a mismatch
    seq += [step] * 40 + [bg] * 10  # an LED step, re-learnt
    return seq


def _fields(r: object) -> tuple:
    return tuple(getattr(r, n) for n in ("contact", "area_px", "saturation_seen", "background_ready", "mismatch",
                                         "invalid", "deformation", "gain", "offset")) + tuple(
        getattr(r, n).tobytes() for n in ("thumb", "reduced", "mask"))


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__)
        return 2
    rev, reps = argv[0], int(argv[1]) if len(argv) > 1 else 30
    logging.disable(logging.CRITICAL)
    from tactile_force.edge.gate.contact_gate import ContactGate

    from .frames import frame_pool

    old = old_gate_module(rev)
    cv2.setNumThreads(1)
    pool = frame_pool()
    bgs = list(pool.background)
    seq = sequence(bgs[0], pool.rgb)

    a, b = old.ContactGate(), ContactGate()
    a.capture_background(bgs)
    b.capture_background(bgs)
    for f in seq:
        if _fields(a.update(f)) != _fields(b.update(f)):
            print("NOT bit-identical")
            return 1
    relearned = b.relearned
    if a.relearned != b.relearned or a.state != b.state:
        print("NOT bit-identical (state)")
        return 1
    a, b = old.ContactGate(), ContactGate()  # learnt from the live frames, then reset
    for frames in (bgs + seq, bgs + seq[:40]):
        for f in frames:
            if _fields(a.update(f)) != _fields(b.update(f)):
                print("NOT bit-identical (live-learnt background)")
                return 1
        a.reset()
        b.reset()
    print(f"bit-identical on {len(seq)} frames (re-learnt {relearned}x)")

    t_old: list[int] = []
    t_new: list[int] = []
    clock = time.perf_counter_ns
    for rep in range(reps):
        a, b = old.ContactGate(), ContactGate()
        a.capture_background(bgs)
        b.capture_background(bgs)
        for k, f in enumerate(seq):
            pair = ((a, t_old), (b, t_new)) if (k + rep) % 2 else ((b, t_new), (a, t_old))
            for g, out in pair:
                t = clock()
                g.update(f)
                out.append(clock() - t)
    po, pn = statistics.median(t_old), statistics.median(t_new)
    print(f"per frame: {rev} p50 {po / 1000:.1f} us, current p50 {pn / 1000:.1f} us, new/old {pn / po:.3f} "
          f"(sum new/old {sum(t_new) / sum(t_old):.3f}; {len(t_old)} frames each)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
