"""The frame contract: uint8 H x W x 3 BGR, DIGIT portrait 320 rows x 240 columns.

All sources yield frames in this convention with a monotonic timestamp in nanoseconds
(:class:`TimedFrame`). :func:`check_frame` is the single validator used everywhere a frame
enters the package.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from .errors import FrameError

#: DIGIT frame size after orientation: rows, columns (portrait).
FRAME_ROWS = 320
FRAME_COLS = 240
FRAME_SHAPE = (FRAME_ROWS, FRAME_COLS, 3)

#: Most frames one model call takes, and so most sensors one runtime serves (one frame per
#: sensor per call). Each frame still needs its own contact-gate pass, about 0.4 to 1 ms on
#: one core, so 16 sensors at 60 fps fill one core's 16.7 ms frame period: a hand or two
#: (fingertips and palm pads) fit; more sensors need a second runtime.
MAX_BATCH = 16

_UINT8 = np.dtype(np.uint8)

#: Mean intensity (0..255) under which a frame counts as all-dark, over which all-white.
DARK_LEVEL = 8.0
WHITE_LEVEL = 247.0


@dataclass(slots=True)
class TimedFrame:
    """One frame from a source.

    frame: HxWx3 uint8 BGR; timestamp_ns: the frame's own time stamp (capture or playback
    time, monotonic ns; for the virtual DIGIT its exact place in the 60 fps stream);
    index: running frame number of the source; truth_n: ground-truth normal force in N when
    the source knows it (replay of a labelled dataset, the virtual DIGIT), else None;
    arrival_ns: when the source had the frame, on the source's monotonic clock (ns): a
    camera frame when the grab returned, a paced replay frame when it fell due, a decoded
    or rendered frame when it was ready. The runtime's total latency and ``late`` flag
    count from it; None (a source that does not stamp arrival) means "when read()
    returned it". Every source in this package sets it.
    """

    frame: np.ndarray
    timestamp_ns: int
    index: int
    truth_n: float | None = None
    meta: dict = field(default_factory=dict)
    arrival_ns: int | None = None


def check_frame(
    frame: object,
    name: str = "frame",
    shape: tuple[int, int, int] | None = FRAME_SHAPE,
) -> np.ndarray:
    """Validate a frame and return it as a C-contiguous uint8 array.

    Raises :class:`FrameError` naming ``name`` on a non-array, wrong dtype, wrong shape,
    or an empty array. ``shape=None`` accepts any H x W x 3.
    """
    if type(frame) is np.ndarray and frame.dtype is _UINT8 and frame.flags.c_contiguous and (
            frame.shape == shape if shape is not None
            else frame.ndim == 3 and frame.shape[2] == 3 and frame.size):  # the usual frame: as it is
        return frame
    if not isinstance(frame, np.ndarray):
        raise FrameError(f"{name}: expected a numpy.ndarray (H x W x 3 uint8 BGR), got {type(frame).__name__}")
    if frame.size == 0:
        raise FrameError(f"{name}: empty array (shape {frame.shape}); expected H x W x 3 uint8 BGR")
    nan = np.issubdtype(frame.dtype, np.floating) and not np.all(np.isfinite(frame))
    problem = frame_layout_problem(frame.shape, frame.dtype, shape, nan=nan)
    if problem is not None:
        raise FrameError(f"{name}: {problem}")
    return np.ascontiguousarray(frame)


def frame_layout_problem(shape: tuple[int, ...], dtype: np.dtype | type,
                         expected: tuple[int, int, int] | None = FRAME_SHAPE, nan: bool = False) -> str | None:
    """What :func:`check_frame` refuses in an image of this shape and dtype, from the layout
    alone (no pixels needed: a reader can judge an image file by its header), else None.

    Parameters
    ----------
    shape, dtype
        The image's array shape (H x W, or H x W x C) and element type.
    expected
        H x W x 3 the frame must have; None accepts any H x W x 3.
    nan
        The values hold NaN or inf (said in the message of a float image).

    Returns
    -------
    str or None
        E.g. ``"shape (320, 240); expected H x W x 3 (BGR)"`` for a grey image.
    """
    if np.dtype(dtype) != np.uint8:
        extra = " (and it contains NaN or inf)" if nan else ""
        return (f"dtype {np.dtype(dtype)}{extra}; expected uint8 BGR 0..255 "
                "(convert with np.clip(x, 0, 255).astype(np.uint8) only if the values are 0..255)")
    if len(shape) != 3 or shape[2] != 3:
        return f"shape {tuple(shape)}; expected H x W x 3 (BGR)"
    if expected is not None and tuple(shape) != tuple(expected):
        hint = ""
        if tuple(shape[:2]) == tuple(expected[:2][::-1]):
            hint = " (looks like landscape: transpose/rotate to 320 rows x 240 cols as digit-interface does)"
        return f"shape {tuple(shape)}; expected {tuple(expected)}{hint}"
    return None


#: Share of pixels clipped at the top (a channel >= 250) above which a frame is over-exposed.
CLIPPED_SHARE = 0.5


def check_batch(x: object, name: str, shape: tuple[int, ...], max_batch: int | None = None) -> np.ndarray:
    """Validate a model input batch (N, *shape) uint8, e.g. (N, 320, 240, 3) BGR frames or
    (N, 320, 240, 1) depth images; FrameError naming ``name`` otherwise. Every inference
    backend (CPU, OAK) checks its inputs with this."""
    if (type(x) is np.ndarray and x.dtype is _UINT8 and x.ndim == len(shape) + 1 and x.shape[1:] == tuple(shape)
            and x.shape[0] >= 1 and (max_batch is None or x.shape[0] <= max_batch)):
        return x  # the usual batch (the messages below are built only for a bad one)
    want = f"(N, {', '.join(map(str, shape))}) uint8"
    if not isinstance(x, np.ndarray):
        raise FrameError(f"{name}: expected a numpy.ndarray {want}, got {type(x).__name__}")
    if x.size == 0:
        raise FrameError(f"{name}: empty array (shape {x.shape}); expected {want}, N >= 1")
    if x.dtype != np.uint8:
        nan = " and contains NaN/inf" if np.issubdtype(x.dtype, np.floating) and not np.isfinite(x).all() else ""
        raise FrameError(f"{name}: dtype {x.dtype}{nan}; expected uint8 (BGR 0..255, scaling is inside the graph)")
    if x.ndim != len(shape) + 1 or x.shape[1:] != tuple(shape):
        raise FrameError(f"{name}: shape {x.shape}; expected {want}")
    if max_batch is not None and not 1 <= x.shape[0] <= max_batch:
        raise FrameError(f"{name}: batch {x.shape[0]}; this model takes 1..{max_batch} frames per call")
    return x


def exposure_problem(frame: np.ndarray) -> str | None:
    """Return 'all-dark', 'all-white' or 'over-exposed' when a frame carries no usable
    image, else None.

    all-dark / all-white: mean intensity below DARK_LEVEL / above WHITE_LEVEL;
    over-exposed: at least CLIPPED_SHARE of the pixels have a channel clipped (>= 250),
    e.g. LEDs driven far too bright, where the colour cues of contact are lost.
    """
    # Every pixel counts (a strided sample reads a fine 0/255 pattern as all-white); cv2.mean
    # and inRange are SIMD passes over the frame, tens of microseconds for 320x240x3.
    import cv2  # here, so that importing tactile_force.edge stays light

    m = cv2.mean(frame)
    cn = frame.shape[2] if frame.ndim == 3 else 1
    # the mean of the channel means, summed in order as np.mean of up to 4 values does
    mean = (m[0] + m[1] + m[2]) / 3.0 if cn == 3 else float(np.mean(m[:cn]))
    if mean < DARK_LEVEL:
        return "all-dark"
    if mean > WHITE_LEVEL:
        return "all-white"
    if mean > 128.0:
        unclipped = cv2.inRange(frame, (0, 0, 0), (249, 249, 249)) if frame.ndim == 3 else cv2.inRange(frame, 0, 249)
        if 1.0 - cv2.countNonZero(unclipped) / unclipped.size >= CLIPPED_SHARE:
            return "over-exposed"
    return None


@dataclass(slots=True)
class SourceStats:
    """Counters every source keeps: frames delivered, dropped (never arrived or
    superseded) and corrupt (arrived but undecodable or wrong shape; never passed on)."""

    frames: int = 0
    dropped: int = 0
    corrupt: int = 0


class FrameReader(Protocol):
    """What a runtime reads a sensor through: :meth:`read` and :meth:`close`
    (:class:`FrameSource` is the base of every source in this package; a source of your own
    needs these two members, checked when a ``Sensor`` is made)."""

    def read(self) -> TimedFrame | None:
        """The next frame, or None at the end of a finite stream (see :class:`FrameSource`)."""
        ...

    def close(self) -> None:
        """Release the device or file; safe to call twice."""
        ...


class FrameSource:
    """Interface of every frame source (camera, replay folder, video file, virtual DIGIT).

    ``read()`` returns the next :class:`TimedFrame`, or None at the end of a finite
    stream; it raises :class:`~tactile_force.edge.errors.SourceError` when the device or
    file is gone. Corrupt frames are counted in ``stats.corrupt`` and skipped, never
    returned. Sources are context managers and iterables of TimedFrame.
    """

    name: str = "source"

    def __init__(self) -> None:
        self.stats = SourceStats()

    def read(self) -> TimedFrame | None:  # pragma: no cover - interface
        raise NotImplementedError

    def close(self) -> None:
        """Release the device or file; safe to call twice."""

    def __enter__(self) -> FrameSource:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __iter__(self):
        while (item := self.read()) is not None:
            yield item
