"""One downscale per frame: a full-resolution frame -> the network's input resolution.

A compact bundle's graph starts at the network resolution (e.g. 80 x 60 for input scale
1/4); the runtime reduces each frame ONCE, the contact gate judges that reduced image and the
model is handed the same array. The bundle's manifest records how the frame is reduced
(:class:`~tactile_force.edge.bundle.manifest.FrameReduction`), training and export reduce the same
way (``tactile_force.export.preprocess`` replicates these functions in torch, bit for bit),
and this module is the one implementation the runtime uses.

Methods (:class:`~tactile_force.edge.bundle.manifest.Reduction`):

``none``
    The graph takes the full-resolution frame (the paper authors' checkpoints, format-2
    bundles).
``area``
    One k x k box average (OpenCV ``INTER_AREA`` at an integer factor), rounded to the
    nearest integer, ties to even. At k = 4 this is exactly what the in-graph ``AveragePool``
    followed by the uint8 input quantizer (scale 1, zero point 0) of the format-2 default
    graph computed.
``area-2x-steps``
    log2(k) successive exact 2 x 2 box averages (OpenCV ``INTER_AREA`` at exactly 1/2), each
    rounded half up: (a + b + c + d + 2) >> 2. Within one grey level of ``area``; about 3x
    faster on a 320 x 240 x 3 frame because OpenCV's 2 x 2 path is vectorised
    (docs/benchmarks/one_downscale.md). ``cv2.pyrDown`` is not used: it is a 5 x 5 Gaussian,
    not a box average.
"""

from __future__ import annotations

import cv2
import numpy as np

from ..bundle.manifest import FrameReduction, Reduction
from ..errors import FrameError

__all__ = ["FrameReducer", "default_reduction", "reduce_frames", "reduced_shape"]


def default_reduction(factor: int) -> FrameReduction:
    """The package's reduction for an integer ``factor``: ``none`` at 1, ``area-2x-steps`` for a
    power of two (the fastest exact box average), else ``area``."""
    f = int(factor)
    if f < 1:
        raise ValueError(f"reduction factor {factor}: expected an integer >= 1")
    if f == 1:
        return FrameReduction(Reduction.NONE, 1)
    if f & (f - 1) == 0:
        return FrameReduction(Reduction.AREA_2X_STEPS, f)
    return FrameReduction(Reduction.AREA, f)


def reduced_shape(shape: tuple[int, ...], reduction: FrameReduction) -> tuple[int, int, int]:
    """(rows, cols, channels) of an H x W x C frame after ``reduction`` (H, W divisible by k)."""
    h, w, c = int(shape[0]), int(shape[1]), int(shape[2]) if len(shape) > 2 else 1
    k = reduction.factor
    if h % k or w % k:
        raise FrameError(f"frame {h}x{w}: not divisible by the reduction factor {k}")
    return h // k, w // k, c


class FrameReducer:
    """Reduce H x W x C uint8 frames by ``reduction`` into buffers allocated once.

    Parameters
    ----------
    reduction
        How to reduce (method and factor k).
    shape
        (H, W, C) of the full-resolution frames (H and W divisible by k).

    ``reducer(frame)`` returns the reduced (H/k, W/k, C) uint8 image in the reducer's own
    buffer (overwritten by the next call: copy it to keep it); ``reducer(frame, out=arr)``
    writes into ``arr`` instead. ``calls`` counts the frames reduced (the one-downscale
    tests read it).
    """

    def __init__(self, reduction: FrameReduction, shape: tuple[int, int, int]) -> None:
        self.reduction = reduction
        self.shape = (int(shape[0]), int(shape[1]), int(shape[2]))
        rows, cols, ch = reduced_shape(self.shape, reduction)
        self.out_shape = (rows, cols, ch)
        self.out = np.empty(self.out_shape, np.uint8)
        self.calls = 0
        k = reduction.factor
        self._steps: list[np.ndarray] = []
        if reduction.method is Reduction.AREA_2X_STEPS:
            if k < 2 or k & (k - 1):
                raise ValueError(f"reduction area-2x-steps needs a power-of-two factor >= 2, got {k}")
            h, w = self.shape[:2]
            while k > 2:  # intermediate buffers: H/2, H/4, ... down to H/(k/2)
                h, w, k = h // 2, w // 2, k // 2
                self._steps.append(np.empty((h, w, ch), np.uint8))
        elif reduction.method is Reduction.AREA and k < 2:
            raise ValueError(f"reduction area needs a factor >= 2, got {k}")

    def __call__(self, frame: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        dst = self.out if out is None else out
        m = self.reduction.method
        self.calls += 1
        if m is Reduction.NONE:
            np.copyto(dst, frame.reshape(dst.shape))
            return dst
        if m is Reduction.AREA:
            _resize(frame, dst)
            return dst
        src = frame
        for buf in self._steps:
            _resize(src, buf)
            src = buf
        _resize(src, dst)
        return dst


def _resize(src: np.ndarray, dst: np.ndarray) -> None:
    """INTER_AREA from src into dst (both H x W x C uint8; C = 1 is kept as a third axis)."""
    if dst.ndim == 3 and dst.shape[2] == 1:
        cv2.resize(src.reshape(src.shape[:2]), (dst.shape[1], dst.shape[0]), dst=dst.reshape(dst.shape[:2]),
                   interpolation=cv2.INTER_AREA)
    else:
        cv2.resize(src, (dst.shape[1], dst.shape[0]), dst=dst, interpolation=cv2.INTER_AREA)


def reduce_frames(frames: np.ndarray, reduction: FrameReduction) -> np.ndarray:
    """(N, H, W, C) uint8 -> (N, H/k, W/k, C) uint8 by ``reduction`` (a new array; training,
    calibration and evaluation use it; the runtime uses a :class:`FrameReducer`)."""
    frames = np.asarray(frames)
    if frames.ndim != 4 or frames.dtype != np.uint8:
        raise FrameError(f"frames: shape {frames.shape} dtype {frames.dtype}; expected (N, H, W, C) uint8")
    red = FrameReducer(reduction, frames.shape[1:])
    out = np.empty((len(frames), *red.out_shape), np.uint8)
    for i, f in enumerate(frames):
        red(np.ascontiguousarray(f), out=out[i])
    return out
