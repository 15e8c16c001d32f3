"""A DIGIT-style camera through OpenCV V4L2: size and rate, orientation, VGA halving,
corrupt-frame counting, and keeping only the newest frame."""

from __future__ import annotations

import logging
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from ..checks import expect
from ..errors import SourceError
from ..frames import FRAME_SHAPE, FrameSource, TimedFrame
from ..limits import FPS, bounds
from .common import MAX_CORRUPT_IN_ROW, Clock, StreamLost, check_shape, fit_frame, orient_digit

_log = logging.getLogger(__name__)


class Capture(Protocol):
    """What CameraSource needs of a capture: the cv2.VideoCapture methods it calls."""

    def isOpened(self) -> bool: ...
    def set(self, prop: int, value: float) -> bool: ...
    def get(self, prop: int) -> float: ...
    def read(self) -> tuple[bool, np.ndarray | None]: ...
    def release(self) -> None: ...


def missing_camera(device: int | str) -> str | None:
    """Why V4L2 cannot open camera ``device`` (index, '0', or '/dev/videoN') because its
    /dev node does not exist (an index N is /dev/videoN on Linux), else None. Opens nothing."""
    dev = int(device) if isinstance(device, str) and device.isdigit() else device
    if isinstance(dev, int):
        node = Path(f"/dev/video{dev}")
        if not sys.platform.startswith("linux") or node.exists():
            return None
        return f"camera {dev}: no such device {node} (is the sensor plugged in? see 'tactile-force devices')"
    if not Path(dev).exists():
        return f"camera {dev}: no such device (is the sensor plugged in? see 'tactile-force devices')"
    return None


def open_v4l2(device: int | str) -> cv2.VideoCapture:
    """Default capture factory: ``device`` (index, '0', or '/dev/videoN') through OpenCV's V4L2 backend."""
    if (why := missing_camera(device)) is not None:
        raise SourceError(why)
    dev = int(device) if isinstance(device, str) and device.isdigit() else device
    return cv2.VideoCapture(dev, cv2.CAP_V4L2)


def _fit_camera(frame: np.ndarray | None, shape: tuple[int, int, int], size: tuple[int, int]) -> np.ndarray | None:
    """A camera image in the contract, or None (corrupt). Accepted: ``shape`` itself, its landscape
    transpose (oriented as digit-interface does), or the requested landscape ``size`` (width, height),
    oriented and then resized to ``shape`` with INTER_AREA (VGA -> 320x240)."""
    if frame is None:
        return None
    fitted = fit_frame(frame, shape)
    if fitted is not None or frame.ndim != 3 or frame.dtype != np.uint8:
        return fitted
    if frame.shape == (size[1], size[0], 3):
        out = orient_digit(frame) if size[0] > size[1] else frame
        return cv2.resize(out, (shape[1], shape[0]), interpolation=cv2.INTER_AREA)
    return None


class CameraSource(FrameSource):
    """A DIGIT (or any UVC) camera through OpenCV's V4L2 backend.

    device: index (0) or path ('/dev/video0'). The camera is asked for ``size`` (width, height
    in pixels; default: ``shape`` as landscape, QVGA) at ``fps``, trying each ``fourcc`` in
    turn (MJPG, then YUYV; () leaves the format alone), with a one-frame driver buffer.
    Frames come out as ``shape`` (portrait 320x240 BGR): landscape images are oriented as
    digit-interface does, a larger requested size (VGA) is then resized down.

    grab_thread=True: a grabber thread reads continuously and keeps only the newest frame;
    ``read()`` returns it (waiting up to ``timeout_s``) with the frames it superseded.
    grab_thread=False: ``read()`` grabs in the caller's thread and returns every frame.
    ``max_failures`` failed grabs or ``max_corrupt`` corrupt frames in a row mean the device
    is gone: ``read()`` raises :class:`StreamLost`; ``reopen()`` tries again.

    Hooks: ``open_capture(device)`` makes the capture (default :func:`open_v4l2`; tests pass
    a fake camera); ``configure(capture)`` runs after every open, once size/fps are set
    (e.g. a V4L2 control such as the DIGIT LED zoom value).
    """

    def __init__(self, device: int | str = 0, fps: float = 60.0, fourcc: tuple[str, ...] = ("MJPG", "YUYV"),
                 shape: tuple[int, int, int] = FRAME_SHAPE, timeout_s: float = 1.0, max_failures: int = 30,
                 name: str = "camera", clock: Clock = time.monotonic_ns, *, size: tuple[int, int] | None = None,
                 max_corrupt: int = MAX_CORRUPT_IN_ROW, grab_thread: bool = True,
                 open_capture: Callable[[int | str], Capture] = open_v4l2,
                 configure: Callable[[Capture], None] | None = None) -> None:
        super().__init__()
        expect(device, int | str, "CameraSource.device", "a camera index >= 0 or a /dev/videoN path", ge=0,
               nonempty=True)
        expect(fps, float, "CameraSource.fps", "a frame rate in [0.01, 10000] per second", **bounds(FPS))
        expect(fourcc, tuple[str, ...], "CameraSource.fourcc", "a tuple of FOURCC codes such as ('MJPG', 'YUYV')")
        check_shape(shape, "CameraSource.shape", optional=False)
        expect(size, tuple[int, int] | None, "CameraSource.size", "(width, height) in pixels >= 1, or None", ge=1)
        expect(timeout_s, float, "CameraSource.timeout_s", "a number of seconds in (0, 3600]", gt=0, le=3600)
        expect(max_failures, int, "CameraSource.max_failures", ge=1)
        expect(max_corrupt, int, "CameraSource.max_corrupt", ge=1)
        expect(name, str, "CameraSource.name", nonempty=True)
        expect(clock, Callable, "CameraSource.clock", "a callable returning monotonic ns")
        expect(grab_thread, bool, "CameraSource.grab_thread")
        expect(open_capture, Callable, "CameraSource.open_capture", "a callable opening a capture")
        expect(configure, Callable | None, "CameraSource.configure", "a callable taking the capture, or None")
        self.name = name
        self.device = device
        self.fps = fps
        self.fourcc = tuple(fourcc)
        self.shape = shape
        self.size = size or (max(shape[:2]), min(shape[:2]))
        self.timeout_s = timeout_s
        self.max_failures = max_failures
        self.max_corrupt = max_corrupt
        self.grab_thread = grab_thread
        self._clock = clock
        self._open_capture = open_capture
        self._configure = configure
        self._cap: Capture | None = None
        self._cond = threading.Condition()
        self._latest: TimedFrame | None = None
        self._superseded: list[tuple[int, int]] = []
        self._error: str | None = None
        self._failures = 0
        self._corrupt = 0
        self._index = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._open()

    # -- opening -------------------------------------------------------------------------------
    def _open(self) -> None:
        cap = self._open_capture(self.device)
        if cap is None or not cap.isOpened():
            raise SourceError(f"camera {self.device}: cannot open with V4L2 (missing device, busy, or no permission "
                              "to /dev/video*: add your user to the 'video' group)")
        try:
            for code in self.fourcc:
                fourcc = cv2.VideoWriter.fourcc(*code)
                cap.set(cv2.CAP_PROP_FOURCC, fourcc)
                if int(cap.get(cv2.CAP_PROP_FOURCC)) == fourcc:
                    break
            cap.set(cv2.CAP_PROP_FRAME_WIDTH, self.size[0])
            cap.set(cv2.CAP_PROP_FRAME_HEIGHT, self.size[1])
            cap.set(cv2.CAP_PROP_FPS, self.fps)
            cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
            if self._configure is not None:
                self._configure(cap)
        except BaseException:
            cap.release()
            raise
        self._cap = cap
        self._error = None
        self._failures = self._corrupt = 0
        if self.grab_thread:
            self._stop = threading.Event()
            self._thread = threading.Thread(target=self._grab_loop, args=(cap, self._stop), name=f"grab-{self.name}",
                                            daemon=True)
            self._thread.start()

    def reopen(self, device: int | str | None = None) -> None:
        """Release the capture and open it again, at ``device`` when given (a node number can
        change after a replug). SourceError when it cannot be opened; the source then stays
        closed until a later ``reopen()`` succeeds. Frame indices continue."""
        self.close()
        if device is not None:
            self.device = device
        self._open()

    # -- grabbing ------------------------------------------------------------------------------
    def _grab(self, cap: Capture) -> TimedFrame | None:
        """One grab: a TimedFrame, or None (failed or corrupt: counted, and ``_error`` set once
        the stream counts as lost). Counters change under ``_cond``."""
        ok, img = cap.read()
        ts = self._clock()
        frame = _fit_camera(img, self.shape, self.size) if ok else None
        with self._cond:
            if not ok:
                self._failures += 1
                self.stats.dropped += 1
                if self._failures >= self.max_failures:
                    self._error = f"camera {self.device}: {self._failures} grab(s) failed in a row (device unplugged?)"
                return None
            self._failures = 0
            if frame is None:
                self._corrupt += 1
                self.stats.corrupt += 1
                if self._corrupt >= self.max_corrupt:
                    self._error = (f"camera {self.device}: {self._corrupt} corrupt frames in a row "
                                   f"(undecodable or not {self.size[0]}x{self.size[1]})")
                return None
            self._corrupt = 0
            item = TimedFrame(np.ascontiguousarray(frame), ts, self._index, arrival_ns=ts)
            self._index += 1
            return item

    def _grab_loop(self, cap: Capture, stop: threading.Event) -> None:
        while not stop.is_set():
            item = self._grab(cap)
            with self._cond:
                if stop.is_set():
                    return
                if self._error is not None:
                    self._cond.notify_all()
                    return
                if item is not None:
                    if self._latest is not None:
                        self._superseded.append((self._latest.index, self._latest.timestamp_ns))
                        self.stats.dropped += 1
                    self._latest = item
                    self._cond.notify_all()
                    continue
                failing = self._failures > 0
            if failing:
                time.sleep(0.002)

    def _read_threaded(self) -> TimedFrame:
        with self._cond:
            if not self._cond.wait_for(lambda: self._latest is not None or self._error is not None, self.timeout_s):
                raise StreamLost(f"camera {self.device}: no frame for {self.timeout_s:.1f} s")
            if self._latest is None:
                raise StreamLost(self._error or f"camera {self.device}: stopped")
            item, self._latest = self._latest, None
            item.meta["superseded"], self._superseded = self._superseded, []
            return item

    def _read_direct(self, cap: Capture) -> TimedFrame:
        while True:
            item = self._grab(cap)
            if item is not None:
                item.meta["superseded"] = []
                return item
            if self._error is not None:
                raise StreamLost(self._error)
            if self._failures:
                time.sleep(0.002)

    def read(self) -> TimedFrame:
        """Next frame (never None: a camera stream has no end). StreamLost when the device
        stopped delivering, SourceError when the source is closed."""
        cap = self._cap
        if cap is None:
            raise SourceError(f"camera {self.device}: source is closed")
        item = self._read_threaded() if self.grab_thread else self._read_direct(cap)
        self.stats.frames += 1
        return item

    def close(self) -> None:
        """Stop the grabber thread and release the capture; safe to call twice."""
        self._stop.set()
        if self._thread is not None and self._thread.is_alive():
            self._thread.join(timeout=1.0)
        self._thread = None
        cap, self._cap = self._cap, None
        if cap is not None:
            cap.release()
        with self._cond:
            if self._latest is not None:  # never read: superseded by whatever comes after a reopen
                self._superseded.append((self._latest.index, self._latest.timestamp_ns))
                self.stats.dropped += 1
                self._latest = None
