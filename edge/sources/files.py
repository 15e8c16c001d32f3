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

import logging
import os
import re
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

import cv2
import numpy as np

from ..checks import expect
from ..data.dataset import AuthorsDataset, read_image
from ..data.labels import LabelError, read_force_file
from ..errors import DatasetError, OptionsError, SourceError
from ..frames import FRAME_SHAPE, FrameSource, TimedFrame

Clock = Callable[[], int]
_log = logging.getLogger(__name__)


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


def _check_shape(shape: object, name: str, optional: bool = True) -> None:
    """A frame shape argument: (rows, cols, 3) with rows, cols >= 1 (or None when ``optional``)."""
    want = "(rows, cols, 3) in pixels" + (", or None (any size)" if optional else "")
    expect(shape, tuple[int, int, int] | None if optional else tuple[int, int, int], name, want, ge=1)
    if shape is not None and shape[2] != 3:  # type: ignore[index]
        raise OptionsError(f"{name}={shape!r}: expected {want} (BGR frames have 3 channels)")


#: This many undecodable or wrong-size frames in a row mean the stream is dead.
MAX_CORRUPT_IN_ROW = 30


class StreamLost(SourceError):
    """A camera stopped delivering (grabs failing or only corrupt frames); ``reopen()`` may bring it back."""


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
    fitted = _fit(frame, shape)
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
        expect(fps, float, "CameraSource.fps", "a frame rate > 0 (frames per second)", gt=0)
        expect(fourcc, tuple[str, ...], "CameraSource.fourcc", "a tuple of FOURCC codes such as ('MJPG', 'YUYV')")
        _check_shape(shape, "CameraSource.shape", optional=False)
        expect(size, tuple[int, int] | None, "CameraSource.size", "(width, height) in pixels >= 1, or None", ge=1)
        expect(timeout_s, float, "CameraSource.timeout_s", "a number of seconds > 0", gt=0)
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


def _natural_key(p: Path) -> tuple:
    return tuple(int(t) if t.isdigit() else t for t in re.split(r"(\d+)", p.name))


class _FileSequenceSource(FrameSource):
    """Base for finite file sources: optional real-time pacing at ``fps``.

    Unpaced (fps=None): every frame is returned, stamped with the clock at read time; it
    arrives (``arrival_ns``) when it is decoded. Paced: frame i is due, and arrives, at
    t0 + i/fps; ``read()`` sleeps until the next frame is due and, when the reader fell
    behind, skips to the newest due frame, listing the skipped ones as superseded.
    """

    def __init__(self, fps: float | None, clock: Clock, sleep: Callable[[float], None]) -> None:
        super().__init__()
        owner = type(self).__name__
        expect(fps, float | None, f"{owner}.fps", "a frame rate > 0 or None (unpaced)", gt=0)
        expect(clock, Callable, f"{owner}.clock", "a callable returning monotonic ns")
        expect(sleep, Callable, f"{owner}.sleep", "a callable sleeping for seconds")
        expect(self.name, str, f"{owner}.name", nonempty=True)
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
            return TimedFrame(frame, ts, i, truth, meta, arrival_ns=ts if self.fps is not None else self._clock())
        return None


class ReplayFolderSource(_FileSequenceSource):
    """Replay a folder: the authors' layout (``images/N.png`` + ``forces/force_N.txt``,
    truth_n from the force files, frames in order of N) or a plain folder of PNG/JPG files
    (natural name order, no truth). ``fps=None`` replays as fast as it is read.

    Refused at open, before any frame is read (SourceError naming the file): a frame file
    that is a dangling link, unreadable or a special file; in the authors' layout also a
    frame the runtime would refuse (grey, RGBA, 16-bit, not ``shape``: the labelled data are
    read by :class:`~tactile_force.edge.data.dataset.AuthorsDataset`, frames as they are, never
    converted) and a label file that is a dangling link or unreadable.

    Labels are read by :func:`tactile_force.edge.data.labels.read_force_file`. A bad label
    (missing, not UTF-8, not a number, NaN, negative, above the bound) never stops the
    replay: the frame is yielded with ``truth_n = None`` and ``meta['label_error']``, and
    one warning per bad label file is logged. A frame file that is gone when its turn
    comes (folder deleted or unmounted mid-run) raises SourceError."""

    def __init__(self, path: str | os.PathLike, fps: float | None = None,
                 shape: tuple[int, int, int] | None = FRAME_SHAPE, name: str = "replay",
                 clock: Clock = time.monotonic_ns, sleep: Callable[[float], None] = time.sleep) -> None:
        self.name = name
        super().__init__(fps, clock, sleep)
        expect(path, (str, os.PathLike), "ReplayFolderSource.path", "a replay folder path", nonempty=True)
        _check_shape(shape, "ReplayFolderSource.shape")
        self.path = Path(path)
        self.shape = shape
        if not self.path.is_dir():
            raise SourceError(f"replay folder {self.path}: not found "
                              "(expected images/N.png + forces/ or a folder of PNGs)")
        self._dataset: AuthorsDataset | None = None
        if (self.path / "images").is_dir():
            try:  # labelled data: every frame judged now, as the runtime would (AuthorsDataset)
                self._dataset = AuthorsDataset(self.path, shape=shape)
            except DatasetError as exc:
                raise SourceError(f"replay folder {self.path}: {exc}") from None
            self._files = [self._dataset.image_path(n) for n in self._dataset.ids]
        else:
            self._files = sorted((p for p in self.path.iterdir() if p.suffix.lower() in (".png", ".jpg", ".jpeg")),
                                 key=_natural_key)
            from ..files.guard import special_file_kind

            for p in self._files:  # refused now, not after a run that skipped them
                if (kind := special_file_kind(p)) is not None:  # reading a FIFO would block
                    raise SourceError(f"replay folder {self.path}: {p.name} is a {kind}; expected image files")
                if p.is_symlink() and not p.exists():
                    raise SourceError(f"replay folder {self.path}: {p.name} is a dangling symbolic link (its target "
                                      f"{os.readlink(p)} does not exist); expected image files")
                if not p.is_file() or not os.access(p, os.R_OK):
                    why = "not a regular file" if not p.is_file() else "not readable (permissions)"
                    raise SourceError(f"replay folder {self.path}: {p.name} is {why}; expected image files")
        if not self._files:
            raise SourceError(f"replay folder {self.path}: no .png/.jpg frames")
        self.layout = "authors" if self._dataset is not None else "plain"
        self._warned: set[Path] = set()

    def __len__(self) -> int:
        return len(self._files)

    def _load(self, i: int) -> tuple[np.ndarray | None, float | None, dict]:
        path = self._files[i]
        if not path.is_file():
            raise SourceError(f"replay folder {self.path}: frame {path.name} disappeared during the run "
                              "(folder deleted, moved or unmounted?)")
        if self._dataset is not None:  # labelled frames: read as the dataset reads them (never converted)
            try:
                frame: np.ndarray | None = read_image(path, shape=self._dataset.shape)
            except DatasetError:
                frame = None  # changed since the folder was opened (truncated): counted corrupt
        else:
            img = cv2.imread(str(path), cv2.IMREAD_COLOR)
            frame = _fit(img, self.shape) if img is not None else None
        truth = None
        meta: dict = {"path": str(path)}
        if frame is not None and self._dataset is not None:
            label = self._dataset.force_path(self._dataset.ids[i])
            try:
                truth = read_force_file(label)
            except LabelError as exc:
                meta["label_error"] = str(exc)
                if label not in self._warned:
                    self._warned.add(label)
                    _log.warning("%s: frame replayed without truth: %s", self.name, exc)
        return frame, truth, meta


class VideoFileSource(_FileSequenceSource):
    """Frames of a video file (any format OpenCV reads). ``fps=None``: as fast as read."""

    def __init__(self, path: str | os.PathLike, fps: float | None = None,
                 shape: tuple[int, int, int] | None = FRAME_SHAPE, name: str = "video",
                 clock: Clock = time.monotonic_ns, sleep: Callable[[float], None] = time.sleep) -> None:
        self.name = name
        super().__init__(fps, clock, sleep)
        expect(path, (str, os.PathLike), "VideoFileSource.path", "a video file path", nonempty=True)
        _check_shape(shape, "VideoFileSource.shape")
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
            self._cap.release()
            raise SourceError(f"video file {self.path}: no frames")
        w, h = int(self._cap.get(cv2.CAP_PROP_FRAME_WIDTH)), int(self._cap.get(cv2.CAP_PROP_FRAME_HEIGHT))
        if shape is not None and (h, w) not in (shape[:2], shape[:2][::-1]):
            self._cap.release()
            raise SourceError(f"video file {self.path}: frames are {w}x{h} pixels; expected {shape[1]}x{shape[0]} "
                              f"or {shape[0]}x{shape[1]} (DIGIT frames; resize or crop the video first)")

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
    every .png/.jpg in a folder (each 320x240 BGR, rows x cols, or its 240x320 landscape
    transpose, oriented as the frames are). SourceError naming the file for a special file
    (FIFO, device: refused before opening), an undecodable image or another size."""
    from ..files.guard import special_file_kind
    from ..frames import FRAME_SHAPE

    p = Path(path)
    if p.is_dir():
        files = sorted((f for f in p.iterdir() if f.suffix.lower() in (".png", ".jpg", ".jpeg")), key=_natural_key)
    else:
        files = [p]
    out = []
    for f in files:
        if (kind := special_file_kind(f)) is not None:  # cv2.imread of a FIFO blocks until someone writes
            raise SourceError(f"background image {f}: is a {kind}; expected a no-contact frame image file")
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise SourceError(f"background image {f}: missing or not decodable (expected a no-contact frame)")
        fitted = _fit(img, FRAME_SHAPE)
        if fitted is None:
            raise SourceError(f"background image {f}: {img.shape[0]}x{img.shape[1]} pixels (rows x cols); expected "
                              f"a {FRAME_SHAPE[0]}x{FRAME_SHAPE[1]} no-contact frame of the same sensor as the frames "
                              f"(or its {FRAME_SHAPE[1]}x{FRAME_SHAPE[0]} landscape view)")
        out.append(fitted)
    if not out:
        raise SourceError(f"background folder {p}: no .png/.jpg images")
    return out
