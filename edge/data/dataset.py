"""Labelled data in the paper authors' layout.

    root/images/N.png                  RGB tactile frame (BGR PNG as OpenCV writes it)
    root/filt_img_depth/depth_img_N.png  filtered 8-bit depth image (optional)
    root/forces/force_N.txt            first line = normal force in N
    root/meta.jsonl                    optional, ours: one JSON object per sample with "id"

Labels and meta.jsonl are read by :mod:`tactile_force.edge.data.labels` (the one label reader:
UTF-8, finite, 0 <= F <= 200 N), so every reader accepts and refuses the same files.

Samples are paired by their number N, never by directory listing order.
"""

from __future__ import annotations

import errno
import json
import os
import re
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import cv2
import numpy as np

from ..checks import expect
from ..errors import DatasetError
from ..frames import FRAME_SHAPE, frame_layout_problem
from .labels import LabelError, check_force, read_force_file, read_meta

__all__ = ["AuthorsDataset", "AuthorsDatasetWriter", "LabelError", "Sample", "check_image_file", "read_force_file",
           "read_image"]

_IMG_RE = re.compile(r"^(\d+)\.png$")
#: Image suffixes that are not the layout's PNG: such a file in images/ is refused, never skipped.
_OTHER_IMAGE_SUFFIXES = (".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp", ".gif", ".ppm", ".pgm", ".png")


def _image_ids(img_dir: Path) -> dict[int, Path]:
    """Sample number -> image file of an ``images/`` folder. DatasetError naming the files
    when two names map to one number (``01500.png`` beside ``1500.png``) or an image file is
    not named N.png (``7.jpg``, ``7.PNG``, ``7 (copy).png``): it would be skipped silently.
    Hidden files (a writer's ``.N.png.tmp``) and non-image files are ignored."""
    from ..files.guard import check_input

    out: dict[int, Path] = {}
    for p in sorted(img_dir.iterdir()):
        if p.name.startswith("."):
            continue
        m = _IMG_RE.match(p.name)
        if m is None:
            if p.suffix.lower() in _OTHER_IMAGE_SUFFIXES:
                raise DatasetError(f"{p}: not named N.png; the authors' layout holds PNG frames named by their sample "
                                   f"number (images/N.png with forces/force_N.txt): convert or rename it, or move it "
                                   "out of the folder (it would be skipped)")
            continue
        check_input(p, "frame", "a PNG file")
        n = int(m.group(1))
        if n in out:
            raise DatasetError(f"{out[n]} and {p}: both are sample {n} (one label forces/force_{n}.txt for two "
                               "frames); expected one image per sample number: remove or renumber one")
        out[n] = p
    return out


def duplicate_frames(frames: dict[str, np.ndarray]) -> list[tuple[str, str]]:
    """Pairs (first, later) of names whose frames hold the same pixels (same shape, dtype and
    bytes; compared by SHA-256), in the order of ``frames``."""
    import hashlib

    seen: dict[bytes, str] = {}
    out = []
    for name, frame in frames.items():
        a = np.ascontiguousarray(frame)
        key = hashlib.sha256(f"{a.shape}{a.dtype}".encode() + a.tobytes()).digest()
        if key in seen:
            out.append((seen[key], name))
        else:
            seen[key] = name
    return out


@dataclass(slots=True)
class Sample:
    """One labelled sample: frame HxWx3 uint8 BGR, force in N, optional depth HxW uint8."""

    id: int
    frame: np.ndarray
    force_n: float
    depth: np.ndarray | None = None
    meta: dict = field(default_factory=dict)


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: PNG colour type -> channels OpenCV decodes it to (IMREAD_UNCHANGED); palette (3) and
#: grey + alpha (4) images are decoded to be sure.
_PNG_CHANNELS = {0: 1, 2: 3, 6: 4}


def _png_layout(data: bytes) -> tuple[tuple[int, ...], np.dtype] | None:
    """(shape, dtype) OpenCV decodes a PNG to, from its first 26 bytes (signature + IHDR),
    or None when the header does not settle it (not a PNG, a palette or grey + alpha image)."""
    if len(data) < 26 or data[:8] != _PNG_SIGNATURE or data[12:16] != b"IHDR":
        return None
    width, height = struct.unpack(">II", data[16:24])
    bits, colour = data[24], data[25]
    channels = _PNG_CHANNELS.get(colour)
    if channels is None:
        return None
    shape = (height, width) if channels == 1 else (height, width, channels)
    return shape, np.dtype(np.uint16 if bits == 16 else np.uint8)


def _open_problem(path: Path) -> str | None:
    """Why ``path`` cannot be read as a file (dangling link, folder, permissions), else None."""
    if path.is_symlink() and not path.exists():
        return f"a dangling symbolic link (its target {os.readlink(path)} does not exist)"
    if not path.exists():
        return "missing"
    if not path.is_file():
        return "not a regular file"
    if not os.access(path, os.R_OK):
        return "not readable (permissions)"
    return None


def check_image_file(path: Path, channels: int = 3, shape: tuple[int, int, int] | None = FRAME_SHAPE) -> None:
    """Judge an image file before any work as the runtime judges a frame
    (:func:`~tactile_force.edge.frames.check_frame`): 8-bit, ``channels`` channels (3: BGR
    frame, 1: depth image), ``shape`` rows x cols (None: any size). A PNG is judged by its
    header (no decoding); other images are decoded. An image that cannot be decoded is left
    to its reader (:func:`read_image` refuses it, a replay counts it corrupt and skips it).

    Raises
    ------
    DatasetError
        Naming the file: missing, a dangling link, unreadable, grey or RGBA for a frame
        (colour for a depth image), 16-bit, or another size.
    """
    if (problem := _open_problem(path)) is not None:
        raise DatasetError(f"{path}: {problem}; expected an 8-bit " + _what(channels))
    if path.stat().st_size == 0:  # nothing to decode: as missing as a dangling link
        raise DatasetError(f"{path}: an empty file (0 bytes); expected an 8-bit " + _what(channels))
    try:
        with open(path, "rb") as fh:
            layout = _png_layout(fh.read(26))
    except OSError as exc:
        raise DatasetError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if layout is None:
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
        if img is None:
            return  # undecodable: its reader says so
        layout = (img.shape, img.dtype)
    if (problem := _layout_problem(layout[0], layout[1], channels, shape)) is not None:
        raise DatasetError(f"{path}: {problem}")


def _what(channels: int) -> str:
    return "3-channel BGR frame" if channels == 3 else "single-channel depth image"


def _layout_problem(shape: tuple[int, ...], dtype: np.dtype, channels: int,
                    expected: tuple[int, int, int] | None) -> str | None:
    """What a reader refuses in an image of this layout: the runtime's frame rule for frames,
    8-bit single channel of the frame size for depth images."""
    got = 1 if len(shape) == 2 else shape[2]
    if got != channels or dtype != np.uint8:
        what = {1: "grey", 2: "grey + alpha", 3: "colour", 4: "RGBA"}.get(got, f"{got}-channel")
        return (f"{what} {got}-channel {dtype} image ({shape[0]} x {shape[1]} pixels); expected an 8-bit "
                + _what(channels) + (" (the runtime's frame contract)" if channels == 3 else ""))
    if channels == 3:
        return frame_layout_problem(shape, dtype, expected)
    if expected is not None and tuple(shape[:2]) != tuple(expected[:2]):
        return f"shape {tuple(shape[:2])}; expected {tuple(expected[:2])} (the frame size)"
    return None


def read_image(path: Path, channels: int = 3, shape: tuple[int, int, int] | None = None) -> np.ndarray:
    """Read an 8-bit PNG with ``channels`` channels (3: BGR frame HxWx3, 1: depth image HxW)
    of ``shape`` rows x cols (None: any size).

    DatasetError naming the file if it is missing, undecodable, 16-bit, of another size or
    has another channel count: a colour image is never silently turned grey, nor a grey one
    colour.
    """
    if not path.is_file():  # one stat, as every frame of a replay comes here (a FIFO would block the decoder)
        raise DatasetError(f"{path}: image {_open_problem(path) or 'not a regular file'}")
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None:
        raise DatasetError(f"{path}: cannot decode image (empty, truncated or not an image)")
    if (problem := _layout_problem(img.shape, img.dtype, channels, shape)) is not None:
        raise DatasetError(f"{path}: {problem}")
    return img


class AuthorsDataset:
    """Read a dataset in the authors' layout; index i gives the i-th sample by id order.

    Every frame is judged when the dataset is opened, before any work, as the runtime judges
    a frame (:func:`check_image_file`: an 8-bit BGR image of ``shape``, default the DIGIT's
    320 x 240; None: any size), and every label file and required depth image must be
    readable (a dangling link or an unreadable file is refused): DatasetError naming the
    file. ``require_depth`` makes a missing ``filt_img_depth/depth_img_N.png`` an error;
    otherwise depth is loaded when present.
    """

    def __init__(self, root: str | os.PathLike, require_depth: bool = False,
                 shape: tuple[int, int, int] | None = FRAME_SHAPE) -> None:
        expect(root, (str, os.PathLike), "AuthorsDataset.root", "a dataset folder path", nonempty=True)
        expect(require_depth, bool, "AuthorsDataset.require_depth")
        expect(shape, tuple[int, int, int] | None, "AuthorsDataset.shape", "(rows, cols, 3) in pixels, or None",
               ge=1)
        self.root = Path(root)
        self.shape = shape
        img_dir = self.root / "images"
        if not img_dir.is_dir():
            raise DatasetError(f"{self.root}: no 'images/' folder; "
                               "expected the layout images/N.png, forces/force_N.txt")
        self._images = _image_ids(img_dir)
        if not self._images:
            raise DatasetError(f"{img_dir}: no images named N.png")
        self.ids: list[int] = sorted(self._images)
        self.require_depth = require_depth
        self.meta: dict[int, dict] = read_meta(self.root / "meta.jsonl")
        self._check_files()

    def _check_files(self) -> None:
        """Every frame as the runtime would judge it, every label and required depth image
        readable: DatasetError naming the first file that is not (before any work)."""
        for n in self.ids:
            check_image_file(self.image_path(n), 3, self.shape)
            label = self.force_path(n)
            if (label.exists() or label.is_symlink()) and (problem := _open_problem(label)) is not None:
                raise DatasetError(f"{label}: {problem}; expected the force label of {self.image_path(n).name}")
            if self.require_depth:
                check_image_file(self.depth_path(n), 1, self.shape)

    def __len__(self) -> int:
        return len(self.ids)

    def image_path(self, n: int) -> Path:
        """The image file of sample ``n`` (``images/N.png``, as named on disk)."""
        return self._images.get(n, self.root / "images" / f"{n}.png")

    def depth_path(self, n: int) -> Path:
        return self.root / "filt_img_depth" / f"depth_img_{n}.png"

    def force_path(self, n: int) -> Path:
        return self.root / "forces" / f"force_{n}.txt"

    def force(self, n: int) -> float:
        return read_force_file(self.force_path(n))

    def check_unique(self, samples: list[Sample]) -> None:
        """DatasetError naming both files when two of ``samples`` hold the same frame (a copied
        press would count twice, e.g. in a leave-one-out error that then reads near zero)."""
        dups = duplicate_frames({str(self.image_path(s.id)): s.frame for s in samples})
        if dups:
            a, b = dups[0]
            more = f" (and {len(dups) - 1} more duplicate(s))" if len(dups) > 1 else ""
            raise DatasetError(f"{a} and {b}: the same frame twice{more}; expected each press once (remove the "
                               "copies: a repeated press makes the error estimates too good)")

    def forces(self) -> np.ndarray:
        """All forces in N, in id order."""
        return np.array([self.force(n) for n in self.ids], dtype=np.float64)

    def load(self, n: int) -> Sample:
        """Sample with id ``n``."""
        frame = read_image(self.image_path(n), shape=self.shape)
        dpath = self.depth_path(n)
        depth = None
        if dpath.is_file() or self.require_depth:
            depth = read_image(dpath, channels=1, shape=self.shape)
        return Sample(id=n, frame=frame, force_n=self.force(n), depth=depth, meta=self.meta.get(n, {}))

    def __getitem__(self, i: int) -> Sample:
        return self.load(self.ids[i])

    def __iter__(self) -> Iterator[Sample]:
        for n in self.ids:
            yield self.load(n)


def _fsync_dir(folder: Path) -> None:
    """Make a rename in ``folder`` durable (no-op where directories cannot be opened, e.g. Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError as exc:  # some filesystems cannot fsync a directory; real I/O errors propagate
        if exc.errno not in (errno.EINVAL, errno.EBADF, errno.ENOTSUP):
            raise
    finally:
        os.close(fd)


class AuthorsDatasetWriter:
    """Write samples in the authors' layout, each file atomically (temp + rename).

    The force file is written last, after the image (file and folder entry) and the
    ``meta.jsonl`` line are on disk (fsync), so a crash or power cut leaves at most one
    sample without its label, which readers of this layout report clearly and
    ``tactile-force record --repair`` removes.
    """

    def __init__(self, root: str | os.PathLike, start_id: int = 0) -> None:
        expect(root, (str, os.PathLike), "AuthorsDatasetWriter.root", "a dataset folder path", nonempty=True)
        expect(start_id, int, "AuthorsDatasetWriter.start_id", "a sample number >= 0", ge=0)
        self.root = Path(root)
        for sub in ("images", "forces"):
            (self.root / sub).mkdir(parents=True, exist_ok=True)
        self.next_id = start_id
        self._meta: TextIO | None = None

    @staticmethod
    def _atomic_write(path: Path, data: bytes) -> None:
        tmp = path.with_name(f".{path.name}.tmp")
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)

    def write(self, frame: np.ndarray, force_n: float, depth: np.ndarray | None = None,
              meta: dict | None = None, n: int | None = None) -> int:
        """Write one sample; returns its id N. LabelError before anything is written when
        ``force_n`` is not a valid label (finite, 0..MAX_FORCE_N N)."""
        n = self.next_id if n is None else n
        force_n = check_force(force_n, f"{self.root} sample {n}")
        ok, png = cv2.imencode(".png", frame)
        if not ok:
            raise DatasetError(f"cannot encode frame {n} as PNG (shape {frame.shape}, dtype {frame.dtype})")
        self._atomic_write(self.root / "images" / f"{n}.png", png.tobytes())
        folders = [self.root / "images"]
        if depth is not None:
            (self.root / "filt_img_depth").mkdir(exist_ok=True)
            ok, dpng = cv2.imencode(".png", depth)
            self._atomic_write(self.root / "filt_img_depth" / f"depth_img_{n}.png", dpng.tobytes())
            folders.append(self.root / "filt_img_depth")
        for folder in folders:  # the renames are durable before the label can be
            _fsync_dir(folder)
        if meta is not None:
            if self._meta is None:
                self._meta = open(self.root / "meta.jsonl", "a")  # noqa: SIM115 - kept open across samples
            self._meta.write(json.dumps({"id": n, **meta}) + "\n")
            self._meta.flush()
            os.fsync(self._meta.fileno())
        self._atomic_write(self.root / "forces" / f"force_{n}.txt", f"{force_n:.6f}\n".encode())
        self.next_id = max(self.next_id, n + 1)
        return n

    def close(self) -> None:
        if self._meta is not None:
            self._meta.close()
            self._meta = None

    def __enter__(self) -> AuthorsDatasetWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
