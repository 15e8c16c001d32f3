"""GelSight Mini as a frame source: find it by serial, crop the gel, output the frame contract.

The Mini is a UVC camera (USB 0c45:636d). Capture (V4L2, size/fps/fourcc, orientation,
corrupt-frame counting, StreamLost) is :class:`~tactile_force.edge.sources.CameraSource`;
this module adds what is Mini-specific, following the public GelSight SDK (gsrobotics /
gs_sdk) as facts: the camera is opened at 640x480 here (its sensor is 3280x2464; the SDK
asks for either), a border of ``crop_fraction`` (the SDK's 1/7) of the height is removed
from the top and the bottom and of the width from the left and the right (the gel's edge
and the housing), and the rest is resized to 320x240 landscape, as the SDK's imgw x imgh.

Orientation: that 240x320 landscape image is rotated 90 degrees counter-clockwise into the
frame contract (HxWx3 uint8 BGR, portrait 320 rows x 240 cols), the same rotation
CameraSource gives a DIGIT (transpose, then flip rows): the landscape image's right edge
becomes the top row, its top-left corner the bottom-left corner.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from tactile_force.edge.errors import SourceError
from tactile_force.edge.frames import FRAME_SHAPE, TimedFrame
from tactile_force.edge.sources import CameraSource, Capture, Clock, open_v4l2

from .discovery import AttachedDevice, find_gelsight_mini, locate_sensor

log = logging.getLogger(__name__)

#: The SDK's border: 1/7 of the height (top and bottom) and of the width (left and right).
SDK_CROP_FRACTION = 1.0 / 7.0
#: Landscape (width, height) pixels after the crop: the frame contract turned on its side.
CROPPED_SIZE = (FRAME_SHAPE[0], FRAME_SHAPE[1])


@dataclass
class GelSightMiniOptions:
    """How to open a GelSight Mini.

    sensor: serial ('2BNK-CEGG', the end of its USB product string), index among attached
    Minis (0, 1, ... in serial order) or a /dev/videoN path;
    size: (width, height) pixels asked of the camera, landscape; fps: frames per second asked
    (the driver settles on the nearest it supports); crop_fraction: border removed from each
    side, as a fraction of the height (top, bottom) and of the width (left, right), 0 <= f < 0.5;
    grab_thread: True keeps only the newest frame (live runtime), False returns every frame.
    """

    sensor: str | int = 0
    size: tuple[int, int] = (640, 480)
    fps: float = 25.0
    crop_fraction: float = SDK_CROP_FRACTION
    fourcc: tuple[str, ...] = ("MJPG", "YUYV")
    grab_thread: bool = True
    timeout_s: float = 1.0

    def validate(self) -> None:
        """Raise ValueError naming the first bad field."""
        if not (isinstance(self.crop_fraction, (int, float)) and 0.0 <= self.crop_fraction < 0.5):
            raise ValueError(f"GelSight Mini crop_fraction={self.crop_fraction!r}: expected 0 <= fraction < 0.5 "
                             f"(border removed from each side; the SDK uses 1/7)")
        if (len(self.size) != 2 or not all(isinstance(v, (int, np.integer)) and v > 0 for v in self.size)
                or self.size[0] < self.size[1]):
            raise ValueError(f"GelSight Mini size={self.size!r}: expected (width, height) positive integers, "
                             "landscape (width >= height), e.g. (640, 480)")
        from tactile_force.edge.limits import FPS

        if not FPS.in_range(self.fps) or not self.timeout_s > 0:
            raise ValueError(f"GelSight Mini fps={self.fps}, timeout_s={self.timeout_s}: expected an fps in "
                             f"[{FPS.ge:g}, {FPS.le:g}] and a timeout > 0 s")


def crop_box(width: int, height: int, crop_fraction: float) -> tuple[int, int, int, int]:
    """(x0, y0, x1, y1) pixels of what is kept of a width x height image: floor(fraction *
    width) columns off the left and the right, floor(fraction * height) rows off top and bottom."""
    bx, by = int(width * crop_fraction), int(height * crop_fraction)
    if width - 2 * bx < 1 or height - 2 * by < 1:
        raise ValueError(f"crop_fraction={crop_fraction} leaves nothing of a {width}x{height} image")
    return bx, by, width - bx, height - by


class _CroppingCapture:
    """Wraps the camera: ``read()`` returns the image of ``expect`` (width, height) cropped by
    ``crop_fraction`` and resized (INTER_AREA) to 240x320 landscape, into a buffer reused
    every frame (CameraSource orients it into a new array). Anything else (not BGR uint8, or
    another size) reads as (True, None), which CameraSource counts as corrupt."""

    def __init__(self, cap: Capture, expect: tuple[int, int], crop_fraction: float) -> None:
        self._cap = cap
        self.crop_fraction = crop_fraction
        self._out = np.empty((CROPPED_SIZE[1], CROPPED_SIZE[0], 3), np.uint8)
        self.expect = expect

    @property
    def expect(self) -> tuple[int, int]:
        return self._expect

    @expect.setter
    def expect(self, size: tuple[int, int]) -> None:
        self._expect = (int(size[0]), int(size[1]))
        self._box = crop_box(*self._expect, self.crop_fraction)

    def read(self) -> tuple[bool, np.ndarray | None]:
        ok, img = self._cap.read()
        if not ok:
            return ok, None
        if (img is None or img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3
                or img.shape[:2] != (self._expect[1], self._expect[0])):
            return True, None
        x0, y0, x1, y1 = self._box
        cv2.resize(img[y0:y1, x0:x1], CROPPED_SIZE, dst=self._out, interpolation=cv2.INTER_AREA)
        return True, self._out

    def isOpened(self) -> bool:
        return self._cap.isOpened()

    def set(self, prop: int, value: float) -> bool:
        return self._cap.set(prop, value)

    def get(self, prop: int) -> float:
        return self._cap.get(prop)

    def release(self) -> None:
        self._cap.release()


class GelSightMiniSource(CameraSource):
    """Frames from one GelSight Mini: cropped, 320x240 landscape, rotated to portrait
    (see the module docstring), ``meta['sensor']`` = name.

    A :class:`~tactile_force.edge.sources.CameraSource` opened at the Mini's video node,
    asked for ``options.size``; if the driver settles on another size, that size is cropped
    instead (logged). Frames of any other size or format are counted in ``stats.corrupt``;
    30 in a row raise StreamLost (``reopen()`` tries again). ``open_capture(node)`` returns a
    cv2.VideoCapture-like object (tests pass a fake camera); ``sys_root``/``dev_root``
    locate sysfs and /dev. ``attached``: the discovered device (None for a /dev path that
    discovery does not know). name: defaults to the serial, else the node.
    """

    def __init__(self, options: GelSightMiniOptions | None = None, *, name: str | None = None,
                 clock: Clock = time.monotonic_ns, open_capture: Callable[[int | str], Capture] | None = None,
                 sys_root: str | os.PathLike = "/sys", dev_root: str | os.PathLike = "/dev") -> None:
        self.options = options or GelSightMiniOptions()
        self.options.validate()
        self._roots = (sys_root, dev_root)
        self.attached: AttachedDevice | None = None
        node = self._locate()
        opener = open_capture or open_v4l2
        self._crop: _CroppingCapture | None = None

        def open_cropped(device: int | str) -> _CroppingCapture:
            self._crop = _CroppingCapture(opener(device), self.options.size, self.options.crop_fraction)
            return self._crop

        default = (self.attached.serial if self.attached and self.attached.serial else node) or "gelsight-mini"
        super().__init__(node, fps=self.options.fps, fourcc=self.options.fourcc, timeout_s=self.options.timeout_s,
                         name=name or default, clock=clock, size=tuple(self.options.size),
                         grab_thread=self.options.grab_thread, open_capture=open_cropped,
                         configure=self._adopt_negotiated_size)

    @property
    def node(self) -> str:
        """The /dev/videoN the Mini streams on."""
        return str(self.device)

    @property
    def capture_size(self) -> tuple[int, int]:
        """(width, height) pixels of the images being cropped (the size the driver settled on)."""
        if self._crop is not None:
            return self._crop.expect
        w, h = self.options.size
        return int(w), int(h)

    def _locate(self) -> str:
        self.attached, node = locate_sensor(self.options.sensor, find_gelsight_mini, self._roots)
        return node

    def _adopt_negotiated_size(self, cap: Capture) -> None:
        """CameraSource configure hook: crop what the driver delivers when it is not what was asked."""
        w, h = int(cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if w > 0 and h > 0 and (w, h) != tuple(self.options.size) and self._crop is not None:
            try:
                self._crop.expect = (w, h)
            except ValueError as exc:
                raise SourceError(f"GelSight Mini at {self.device}: the camera streams {w}x{h}: {exc}") from None
            self.size = (w, h)
            log.warning("GelSight Mini %s: asked for %dx%d, the camera streams %dx%d; cropping that",
                        self.device, *self.options.size, w, h)

    def read(self) -> TimedFrame:
        """Next frame, 320x240x3 uint8 BGR portrait (never None); StreamLost when the stream dies."""
        item = super().read()
        item.meta["sensor"] = self.name
        return item
