"""Frame sources: a DIGIT camera (OpenCV V4L2), a replay folder, a video file.

Every source yields :class:`~tactile_force.edge.frames.TimedFrame` in the frame contract
(HxWx3 uint8 BGR, DIGIT portrait 320x240, monotonic ns timestamps). Undecodable or
wrong-size frames are counted in ``stats.corrupt`` and skipped, never passed on.

Superseded frames: a source that runs ahead of its reader (a camera, or a replay paced
at its frame rate) keeps only the newest frame; the ones it skipped are listed in
``TimedFrame.meta['superseded']`` as ``(index, timestamp_ns)`` pairs so the runtime can
report them as ``stale``. There is never a queue of old frames.
"""

from __future__ import annotations

import os
import re
import threading
import time
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from .dataset import AuthorsDataset
from .errors import DatasetError, SourceError
from .frames import FRAME_SHAPE, FrameSource, TimedFrame

Clock = Callable[[], int]


def orient_digit(frame: np.ndarray) -> np.ndarray:
    """DIGIT camera image (240 rows x 320 cols) -> portrait 320x240 as digit-interface does
    (transpose, then flip rows). Frames already 320x240 are returned unchanged."""
    if frame.shape[:2] == FRAME_SHAPE[:2]:
        return frame
    return cv2.flip(cv2.transpose(frame), 0)


def _fit(frame: np.ndarray, shape: tuple[int, int, int] | None) -> np.ndarray | None:
    """Frame in the contract, or None when it cannot be (counted as corrupt by callers)."""
    if frame is None or frame.ndim != 3 or frame.shape[2] != 3 or frame.dtype != np.uint8:
        return None
    if shape is None or frame.shape == shape:
        return frame
    if frame.shape[:2] == shape[:2][::-1]:
        return orient_digit(frame)
    return None


class CameraSource(FrameSource):
    """A DIGIT (or any UVC) camera through OpenCV's V4L2 backend.

    device: index (0) or path ('/dev/video0'). The camera is asked for QVGA at ``fps``,
    MJPG first, then YUYV. A grabber thread reads continuously and keeps only the newest
    frame; ``read()`` returns it (waiting up to ``timeout_s``) with the frames it
    superseded. ``max_failures`` consecutive failed grabs mean the device is gone:
    the next ``read()`` raises SourceError.
    """

    def __init__(self, device: int | str = 0, fps: float = 60.0, fourcc: tuple[str, ...] = ("MJPG", "YUYV"),
                 shape: tuple[int, int, int] = FRAME_SHAPE, timeout_s: float = 1.0, max_failures: int = 30,
                 name: str = "camera", clock: Clock = time.monotonic_ns) -> None:
        super().__init__()
        self.name = name
        self.device = device
        self.shape = shape
        self.timeout_s = timeout_s
        self.max_failures = max_failures
        self._clock = clock
        dev = int(device) if isinstance(device, str) and device.isdigit() else device
        if isinstance(dev, str) and not Path(dev).exists():
            raise SourceError(f"camera {dev}: no such device (is the sensor plugged in? see 'tactile-force devices')")
        cap = cv2.VideoCapture(dev, cv2.CAP_V4L2)
        if not cap.isOpened():
            raise SourceError(f"camera {device}: cannot open with V4L2 (missing device, busy, or no permission "
                              "to /dev/video*: add your user to the 'video' group)")
        for code in fourcc:
            cap.set(cv2.CAP_PROP_FOURCC, cv2.VideoWriter_fourcc(*code))
            if int(cap.get(cv2.CAP_PROP_FOURCC)) == cv2.VideoWriter_fourcc(*code):
                break
        cap.set(cv2.CAP_PROP_FRAME_WIDTH, max(shape[:2]))
        cap.set(cv2.CAP_PROP_FRAME_HEIGHT, min(shape[:2]))
        cap.set(cv2.CAP_PROP_FPS, fps)
        cap.set(cv2.CAP_PROP_BUFFERSIZE, 1)
        self._cap = cap
        self._cond = threading.Condition()
        self._latest: TimedFrame | None = None
        self._superseded: list[tuple[int, int]] = []
        self._error: str | None = None
        self._stop = False
        self._index = 0
        self._thread = threading.Thread(target=self._grab_loop, name=f"grab-{name}", daemon=True)
        self._thread.start()

    def _grab_loop(self) -> None:
        failures = 0
        while not self._stop:
            ok, img = self._cap.read()
            ts = self._clock()
            if not ok:
                failures += 1
                with self._cond:
                    self.stats.dropped += 1
                    if failures >= self.max_failures:
                        self._error = f"camera {self.device}: {failures} grabs failed in a row (device unplugged?)"
                        self._cond.notify_all()
                        return
                time.sleep(0.002)
                continue
            failures = 0
            frame = _fit(img, self.shape)
            with self._cond:
                if frame is None:
                    self.stats.corrupt += 1
                    continue
                if self._latest is not None:
                    self._superseded.append((self._latest.index, self._latest.timestamp_ns))
                    self.stats.dropped += 1
                self._latest = TimedFrame(np.ascontiguousarray(frame), ts, self._index)
                self._index += 1
                self._cond.notify_all()

    def read(self) -> TimedFrame | None:
        with self._cond:
            if not self._cond.wait_for(lambda: self._latest is not None or self._error is not None, self.timeout_s):
                raise SourceError(f"camera {self.device}: no frame for {self.timeout_s:.1f} s")
            if self._latest is None:
                raise SourceError(self._error or f"camera {self.device}: stopped")
            item, self._latest = self._latest, None
            item.meta["superseded"], self._superseded = self._superseded, []
            self.stats.frames += 1
            return item

    def close(self) -> None:
        self._stop = True
        if self._thread.is_alive():
            self._thread.join(timeout=1.0)
        self._cap.release()


def _natural_key(p: Path) -> tuple:
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name))


class _FileSequenceSource(FrameSource):
    """Base for finite file sources: optional real-time pacing at ``fps``.

    Unpaced (fps=None): every frame is returned, stamped with the clock at read time.
    Paced: frame i is due at t0 + i/fps; ``read()`` sleeps until the next frame is due
    and, when the reader fell behind, skips to the newest due frame, listing the skipped
    ones as superseded.
    """

    def __init__(self, fps: float | None, clock: Clock, sleep: Callable[[float], None]) -> None:
        super().__init__()
        if fps is not None and not fps > 0:
            raise SourceError(f"{self.name}: fps={fps}; expected a positive frame rate or None (unpaced)")
        self.fps = fps
        self._clock = clock
        self._sleep = sleep
        self._t0: int | None = None
        self._next = 0

    def __len__(self) -> int:  # pragma: no cover - interface
        raise NotImplementedError

    def _load(self, i: int) -> tuple[np.ndarray | None, float | None, dict]:  # pragma: no cover - interface
        raise NotImplementedError

    def read(self) -> TimedFrame | None:
        superseded: list[tuple[int, int]] = []
        while self._next < len(self):
            i = self._next
            if self.fps is not None:
                period = int(1e9 / self.fps)
                now = self._clock()
                if self._t0 is None:
                    self._t0 = now
                due = self._t0 + i * period
                if due > now:
                    self._sleep((due - now) / 1e9)
                else:
                    newest = min(len(self) - 1, (now - self._t0) // period)
                    if newest > i:
                        superseded += [(k, self._t0 + k * period) for k in range(i, newest)]
                        self.stats.dropped += newest - i
                        i = self._next = int(newest)
                ts = self._t0 + i * period
            else:
                ts = self._clock()
            self._next += 1
            frame, truth, meta = self._load(i)
            if frame is None:
                self.stats.corrupt += 1
                continue
            self.stats.frames += 1
            meta["superseded"] = superseded
            return TimedFrame(frame, ts, i, truth, meta)
        return None


class ReplayFolderSource(_FileSequenceSource):
    """Replay a folder: the authors' layout (``images/N.png`` + ``forces/force_N.txt``,
    truth_n from the force files, frames in order of N) or a plain folder of PNG/JPG files
    (natural name order, no truth). ``fps=None`` replays as fast as it is read."""

    def __init__(self, path: str | os.PathLike, fps: float | None = None, shape: tuple[int, int, int] | None = FRAME_SHAPE,
                 name: str = "replay", clock: Clock = time.monotonic_ns, sleep: Callable[[float], None] = time.sleep) -> None:
        self.name = name
        super().__init__(fps, clock, sleep)
        self.path = Path(path)
        self.shape = shape
        if not self.path.is_dir():
            raise SourceError(f"replay folder {self.path}: not found (expected images/N.png + forces/ or a folder of PNGs)")
        self._dataset: AuthorsDataset | None = None
        if (self.path / "images").is_dir():
            try:
                self._dataset = AuthorsDataset(self.path)
            except DatasetError as exc:
                raise SourceError(f"replay folder {self.path}: {exc}") from None
            self._files = [self._dataset.image_path(n) for n in self._dataset.ids]
        else:
            self._files = sorted((p for p in self.path.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg")),
                                 key=_natural_key)
        if not self._files:
            raise SourceError(f"replay folder {self.path}: no .png/.jpg frames")
        self.layout = "authors" if self._dataset is not None else "plain"

    def __len__(self) -> int:
        return len(self._files)

    def _load(self, i: int) -> tuple[np.ndarray | None, float | None, dict]:
        path = self._files[i]
        img = cv2.imread(str(path), cv2.IMREAD_COLOR)
        frame = _fit(img, self.shape) if img is not None else None
        truth = None
        if frame is not None and self._dataset is not None:
            n = self._dataset.ids[i]
            try:
                truth = self._dataset.force(n)
            except DatasetError:
                truth = None
        return frame, truth, {"path": str(path)}


class VideoFileSource(_FileSequenceSource):
    """Frames of a video file (any format OpenCV reads). ``fps=None``: as fast as read."""

    def __init__(self, path: str | os.PathLike, fps: float | None = None, shape: tuple[int, int, int] | None = FRAME_SHAPE,
                 name: str = "video", clock: Clock = time.monotonic_ns, sleep: Callable[[float], None] = time.sleep) -> None:
        self.name = name
        super().__init__(fps, clock, sleep)
        self.path = Path(path)
        self.shape = shape
        if not self.path.is_file():
            raise SourceError(f"video file {self.path}: not found")
        self._cap = cv2.VideoCapture(str(self.path))
        if not self._cap.isOpened():
            raise SourceError(f"video file {self.path}: OpenCV cannot open it (unknown codec or not a video)")
        self._n = int(self._cap.get(cv2.CAP_PROP_FRAME_COUNT))
        self._pos = 0
        if self._n <= 0:
            raise SourceError(f"video file {self.path}: no frames")

    def __len__(self) -> int:
        return self._n

    def _load(self, i: int) -> tuple[np.ndarray | None, float | None, dict]:
        while self._pos < i:  # skip superseded frames without decoding them
            self._cap.grab()
            self._pos += 1
        ok, img = self._cap.read()
        self._pos += 1
        if not ok:
            if i < self._n - 1:
                return None, None, {}
            self._n = i  # the container over-reported its length
            return None, None, {}
        return _fit(img, self.shape), None, {}

    def close(self) -> None:
        self._cap.release()


def load_background(path: str | os.PathLike) -> list[np.ndarray]:
    """No-contact reference frames for ContactGate.capture_background: one image file, or
    every .png/.jpg in a folder (HxWx3 uint8 BGR)."""
    p = Path(path)
    if p.is_dir():
        files = sorted((f for f in p.iterdir() if f.suffix.lower() in (".png", ".jpg", ".jpeg")), key=_natural_key)
    else:
        files = [p]
    out = []
    for f in files:
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise SourceError(f"background image {f}: missing or not decodable (expected a no-contact frame)")
        out.append(img)
    if not out:
        raise SourceError(f"background folder {p}: no .png/.jpg images")
    return out
