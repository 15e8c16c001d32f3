"""Frame sources from files: a replay folder (plain images, or a labelled folder in the
authors' layout) and a video file, optionally paced at their frame rate.

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
import time
from collections.abc import Callable
from pathlib import Path

import cv2
import numpy as np

from ..checks import expect
from ..data.dataset import AuthorsDataset, read_image
from ..data.labels import LabelError, read_force_file
from ..errors import DatasetError, SourceError
from ..frames import FRAME_SHAPE, FrameSource, TimedFrame
from ..limits import FPS, bounds
from .common import Clock, check_shape, fit_frame, natural_key

_log = logging.getLogger(__name__)


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
        expect(fps, float | None, f"{owner}.fps", "a frame rate in [0.01, 10000] per second, or None (unpaced)",
               **bounds(FPS))
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
        check_shape(shape, "ReplayFolderSource.shape")
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
                                 key=natural_key)
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

    def true_forces(self) -> int:
        """How many frames carry a readable true force (N) in their label file (0 for a folder of
        plain images); read from the label files, the images not decoded."""
        if self._dataset is None:
            return 0
        n = 0
        for i in self._dataset.ids:
            try:
                self._dataset.force(i)
            except LabelError:
                continue
            n += 1
        return n

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
            frame = fit_frame(img, self.shape) if img is not None else None
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
        check_shape(shape, "VideoFileSource.shape")
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
        return fit_frame(img, self.shape), None, {}

    def close(self) -> None:
        self._cap.release()
