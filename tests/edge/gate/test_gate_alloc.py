"""The contact gate's per-frame path allocates no image buffers once warm (every
buffer it works in is allocated with its first frame), measured with tracemalloc on real
OpenCV and virtual DIGIT frames in and out of contact."""

from __future__ import annotations

import tracemalloc

import numpy as np
from tactile_force.edge import ContactGate
from tactile_force.edge.frames import exposure_problem


def _frames() -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """(background, presses, no-contact frames) of a virtual DIGIT."""
    from tactile_force.edge.synthetic import ContactSpec, VirtualDigit, VirtualDigitOptions

    digit = VirtualDigit(VirtualDigitOptions(seed=0))
    bg = digit.render(None, 0.0).frame
    presses = [digit.render(ContactSpec(name, (120 + 10 * i, 160 - 8 * i)), force).frame
               for i, (name, force) in enumerate((("sphere_4mm", 3.0), ("cylinder_8mm", 9.0), ("marble", 14.0)))]
    return bg, presses, [bg, digit.render(None, 0.0).frame]


def _peak_bytes(gate: ContactGate, frame: np.ndarray) -> tuple[int, bool]:
    """Bytes allocated at the peak of one reduce + exposure check + update (the runtime's
    per-frame gate path) above what was allocated before it, and whether it saw contact."""
    before = tracemalloc.get_traced_memory()[0]
    tracemalloc.reset_peak()
    exposure_problem(gate.reduce(frame))
    r = gate.update(frame)
    return tracemalloc.get_traced_memory()[1] - before, r.contact


def test_gate_update_allocates_no_frame_buffers_once_warm():
    bg, presses, free = _frames()
    gate = ContactGate()
    gate.capture_background([bg])
    for f in presses + free:  # warm-up: the first frame allocates the gate's buffers
        gate.reduce(f)
        gate.update(f)
    one_buffer = gate.reduce(bg)[..., 0].nbytes  # one 80 x 60 plane: 4800 bytes
    tracemalloc.start()
    try:
        # A held contact and a free gel. (The onset of a contact after the background was
        # refreshed derives the shift/rotation basis of the background again: allocations
        # on that one frame, not measured here.)
        gate.update(presses[0])
        peaks = [_peak_bytes(gate, f) for _ in range(3) for f in presses]
        gate.update(free[0])
        peaks += [_peak_bytes(gate, f) for _ in range(3) for f in free]
        for f in presses:  # the press's onset: the motion basis is derived and kept
            gate.update(f)
        held = tracemalloc.get_traced_memory()[0]
        for _ in range(20):
            for f in presses[1:] + presses[:1]:
                _peak_bytes(gate, f)
        grown = tracemalloc.get_traced_memory()[0] - held
    finally:
        tracemalloc.stop()
    assert [c for _, c in peaks] == [True] * 9 + [False] * 6
    # What an update may allocate: its GateResult, a few floats and tuples, and the contour
    # points OpenCV returns for each blob (the 14 N marble's outline: several kB); never a
    # working image (80 x 60 x 3 = 14400 bytes) nor, for a small press or a free gel, one
    # 80 x 60 plane (4800 bytes).
    small = [p for i, (p, _) in enumerate(peaks) if i >= 9 or i % 3 < 2]
    assert max(small) < one_buffer, f"one gate update allocated {max(small)} bytes at its peak: {peaks}"
    assert max(p for p, _ in peaks) < 3 * one_buffer, f"one gate update allocated a working image: {peaks}"
    # nothing kept per frame
    assert grown < 1024, f"{grown} bytes more held after 60 more frames"
