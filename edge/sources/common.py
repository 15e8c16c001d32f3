"""What every frame source shares: the clock type, the DIGIT's orientation, fitting a decoded
image to the frame contract, and the camera stream-loss error."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from ..checks import expect
from ..errors import OptionsError, SourceError
from ..frames import FRAME_SHAPE

Clock = Callable[[], int]


def orient_digit(frame: np.ndarray) -> np.ndarray:
    """DIGIT camera image (240 rows x 320 cols) -> portrait 320x240 as digit-interface does
    (transpose, then flip rows). Frames already 320x240 are returned unchanged."""
    if frame.shape[:2] == FRAME_SHAPE[:2]:
        return frame
    return cv2.flip(cv2.transpose(frame), 0)


def fit_frame(frame: np.ndarray, shape: tuple[int, int, int] | None) -> np.ndarray | None:
    """Frame in the contract, or None when it cannot be (counted as corrupt by callers)."""
    if frame is None or frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        return None
    if shape is None or frame.shape == shape:
        return frame
    if frame.shape[:2] == shape[:2][::-1]:
        return orient_digit(frame)
    return None


def check_shape(shape: object, name: str, optional: bool = True) -> None:
    """A frame shape argument: (rows, cols, 3) with rows, cols >= 1 (or None when ``optional``)."""
    want = "(rows, cols, 3) in pixels" + (", or None (any size)" if optional else "")
    expect(shape, tuple[int, int, int] | None if optional else tuple[int, int, int], name, want, ge=1)
    if shape is not None and shape[2] != 3:  # type: ignore[index]
        raise OptionsError(f"{name}={shape!r}: expected {want} (BGR frames have 3 channels)")


#: This many undecodable or wrong-size frames in a row mean the stream is dead.
MAX_CORRUPT_IN_ROW = 30


class StreamLost(SourceError):
    """A camera stopped delivering (grabs failing or only corrupt frames); ``reopen()`` may bring it back."""


def natural_key(p: Path) -> tuple:
    """Sort key of a file name with numbers in numeric order (``2.png`` before ``10.png``)."""
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name))
