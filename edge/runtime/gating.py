"""The gate step of one sensor's frames: the frame contract
(:func:`~tactile_force.edge.frames.check_frame`), the exposure judged on the frame's one
downscale (:func:`~tactile_force.edge.frames.exposure_problem`; box averages keep the mean),
then the contact gate's decision on the same image (the gate and the model read it too)."""

from __future__ import annotations

import numpy as np

from ..errors import FrameError
from ..frames import FRAME_SHAPE, TimedFrame, check_frame, exposure_problem
from ..gate.contact_gate import ContactGate, GateResult

_NO_FRAME = np.zeros((0, 0, 3), np.uint8)


class GateStep:
    """Gate the frames of one sensor.

    Parameters
    ----------
    name : str
        The sensor's name (in the detail of a refused frame).
    gate : ContactGate
        The sensor's contact gate.

    Attributes
    ----------
    frame : numpy.ndarray
        The last frame gated, checked (320 x 240 x 3 uint8 BGR, C-contiguous; empty before
        the first).
    problem : str
        Why the last frame refused was ``invalid_input``.
    """

    __slots__ = ("name", "gate", "frame", "problem")

    def __init__(self, name: str, gate: ContactGate) -> None:
        self.name = name
        self.gate = gate
        self.frame: np.ndarray = _NO_FRAME
        self.problem = ""

    def run(self, tf: TimedFrame) -> GateResult | None:
        """The gate's decision on ``tf``'s frame (then checked in :attr:`frame`), or None when
        the frame breaks the frame contract or is badly exposed (LEDs off, lens covered):
        :attr:`problem` says why."""
        try:
            frame = check_frame(tf.frame, name=f"{self.name} frame {tf.index}", shape=FRAME_SHAPE)
        except FrameError as exc:
            self.problem = str(exc)
            return None
        problem = self._exposure(frame)
        if problem:
            self.problem = f"{self.name} frame {tf.index}: {problem} (LEDs off, lens covered?)"
            return None
        self.frame = frame
        return self.gate.update(frame)

    def _exposure(self, frame: np.ndarray) -> str | None:
        # The frame's one downscale happens here when the gate works reduced: exposure is judged
        # on that image (box averages keep the mean), the gate and the model then read it too.
        gate = self.gate
        return exposure_problem(gate.reduce(frame) if gate.reduction.factor > 1 else frame)

    def prewarm(self) -> None:
        """The work of :meth:`run` once more on the last frame gated (its exposure, then
        :meth:`ContactGate.prewarm`), results thrown away and no state changed: the runtime
        calls it shortly before a frame is due at a slow cadence (edge/runtime/prewarm.py)."""
        frame = self.frame
        if frame.size and self.gate.background_ready:
            self._exposure(frame)
            self.gate.prewarm()
