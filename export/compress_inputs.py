"""What ``compress`` reads: unlabelled frames (image folders, videos, the authors' layout),
labelled frames, and the teacher (a checkpoint or an fp32 bundle) with its outputs cached
under a key of its sha256 and the frames' content (export/compress.py runs it)."""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from tactile_force.edge.bundle.store import load_bundle
from tactile_force.edge.data.dataset import AuthorsDataset, read_image
from tactile_force.edge.errors import DatasetError
from tactile_force.edge.frames import FRAME_SHAPE

from .calibration import CalibrationData
from .checkpoint import model_from_checkpoint
from .compress_options import CompressError
from .onnx_export import ort_session, run_ort
from .preprocess import ForceNet
from .training import predict, preprocess

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp")


VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".webm")


def _check(img: np.ndarray | None, where: str) -> np.ndarray:
    if img is None:
        raise CompressError(f"{where}: cannot read the image (unreadable or not an image)")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    if img.shape != FRAME_SHAPE or img.dtype != np.uint8:
        hint = " (it looks transposed: rotate it to portrait)" if img.shape[:2] == FRAME_SHAPE[1::-1] else ""
        raise CompressError(f"{where}: frame is {img.shape} {img.dtype}; expected {FRAME_SHAPE} uint8 BGR "
                            f"(DIGIT portrait, 320 rows x 240 columns){hint}")
    return img


def read_frames(paths: list[str | os.PathLike], limit: int | None = None) -> tuple[np.ndarray, str]:
    """Unlabelled frames (N,320,240,3) uint8 BGR from folders, videos or authors'-layout datasets."""
    frames: list[np.ndarray] = []
    parts = []
    for raw in paths:
        p = Path(raw)
        before = len(frames)
        if p.is_dir() and (p / "images").is_dir():
            try:  # frames judged at open and read as they are (never converted), as every labelled-data reader
                ds = AuthorsDataset(p)
                frames += [read_image(ds.image_path(n), shape=ds.shape) for n in ds.ids]
            except DatasetError as exc:
                raise CompressError(f"--frames: {exc}") from None
        elif p.is_dir():
            files = sorted(f for f in p.iterdir() if f.suffix.lower() in IMAGE_SUFFIXES and f.is_file())
            if not files:
                raise CompressError(f"--frames {p}: no images ({', '.join(IMAGE_SUFFIXES)}) in this folder")
            frames += [_check(cv2.imread(str(f)), str(f)) for f in files]
        elif p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES:
            cap = cv2.VideoCapture(str(p))
            try:
                while True:
                    ok, img = cap.read()
                    if not ok:
                        break
                    frames.append(_check(img, f"{p} frame {len(frames) - before}"))
            finally:
                cap.release()
            if len(frames) == before:
                raise CompressError(f"--frames {p}: no frames could be decoded from this video")
        elif not p.exists():
            raise CompressError(f"--frames {p}: not found")
        else:
            raise CompressError(f"--frames {p}: expected a folder of images, an authors'-layout dataset or a video "
                                f"({', '.join(VIDEO_SUFFIXES)})")
        parts.append(f"{p} ({len(frames) - before})")
    arr = np.stack(frames) if frames else np.empty((0, *FRAME_SHAPE), np.uint8)
    if limit is not None and len(arr) > limit:
        arr = arr[np.linspace(0, len(arr) - 1, limit).round().astype(int)]
    return arr, ", ".join(parts)


def read_labels(path: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """Labelled frames and forces (N) from an authors'-layout folder."""
    try:
        ds = AuthorsDataset(path)
        samples = [ds.load(n) for n in ds.ids]
    except DatasetError as exc:
        raise CompressError(f"--labels: {exc}") from None
    frames = np.stack([_check(s.frame, str(ds.image_path(s.id))) for s in samples])
    return frames, np.array([s.force_n for s in samples], np.float64)


@dataclass
class Teacher:
    """A teacher model: kind ('checkpoint' | 'bundle'), its file's sha256, a predict function."""

    source: str
    kind: str
    sha256: str
    description: str
    predict: Callable[[np.ndarray], np.ndarray]


def load_teacher(path: str | os.PathLike) -> Teacher:
    """A checkpoint (authors' or ours, RGBmod) or an fp32 RGBmod bundle, as a batch predictor."""
    p = Path(path)
    if p.is_dir() or p.suffix in (".onnx", ".json"):
        b = load_bundle(p)
        if b.manifest.variant.value != "rgbmod":
            raise CompressError(f"teacher {p}: a {b.manifest.variant.value} bundle; compress distils RGBmod "
                                "teachers (students read RGB frames only)")
        session = ort_session(b.onnx_path.read_bytes(), threads=max(1, os.cpu_count() or 1))

        def run_bundle(frames: np.ndarray) -> np.ndarray:
            ids = [str(i) for i in range(len(frames))]
            data = CalibrationData({b.manifest.inputs[0].name: frames}, None, "frames", ids)
            return run_ort(session, data.for_manifest(b.manifest), batch_size=16)

        return Teacher(str(p), "bundle", b.manifest.sha256, f"bundle {b.name} ({b.manifest.precision.value})",
                       run_bundle)
    if not p.is_file():
        raise CompressError(f"teacher {p}: not found (expected a .pth checkpoint or a bundle folder)")
    model, spec, _ = model_from_checkpoint(p, None)
    if spec.variant != "rgbmod":
        raise CompressError(f"teacher {p}: a {spec.variant} checkpoint; compress distils RGBmod teachers")
    net = ForceNet(model, spec).eval()
    sha = hashlib.sha256(p.read_bytes()).hexdigest()

    def run_checkpoint(frames: np.ndarray) -> np.ndarray:
        return predict(model, preprocess(net, {"rgb": frames}, chunk=64), batch=64).astype(np.float64)

    return Teacher(str(p), "checkpoint", sha, f"checkpoint {p.name} (rgbmod w{spec.width:g} "
                   f"input 1/{round(1 / spec.input_scale)})", run_checkpoint)


def frames_digest(*arrays: np.ndarray) -> str:
    """sha256 of the frames' bytes (the teacher-output cache key)."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(str(a.shape).encode())
        h.update(np.ascontiguousarray(a).data)
    return h.hexdigest()


def teacher_outputs(teacher: Teacher, frames: np.ndarray, work: Path, key: str, show: bool) -> np.ndarray:
    """Teacher forces (N,) on ``frames``, computed once and cached in ``work`` under ``key``."""
    cache = work / f"teacher-{key[:24]}.npy"
    if cache.is_file():
        out = np.load(cache)
        if out.shape == (len(frames),):
            return out
    chunk = 64
    parts = []
    from tqdm import tqdm

    for i in tqdm(range(0, len(frames), chunk), desc="teacher", unit="batch", disable=not show, leave=False):
        parts.append(teacher.predict(frames[i:i + chunk]))
    out = np.concatenate(parts) if parts else np.empty(0)
    if not np.all(np.isfinite(out)):
        raise CompressError(f"teacher {teacher.source}: gives non-finite forces on some frames")
    tmp = cache.with_name(cache.name + ".tmp.npy")
    np.save(tmp, out)
    os.replace(tmp, cache)
    return out
