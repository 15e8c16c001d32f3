"""The no-contact background images a contact gate starts from."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

from ..errors import SourceError
from ..frames import FRAME_SHAPE
from .common import fit_frame, natural_key


def load_background(path: str | os.PathLike) -> list[np.ndarray]:
    """No-contact reference frames for ContactGate.capture_background: one image file, or
    every .png/.jpg in a folder (each 320x240 BGR, rows x cols, or its 240x320 landscape
    transpose, oriented as the frames are). SourceError naming the file for a special file
    (FIFO, device: refused before opening), an undecodable image or another size."""
    from ..files.guard import special_file_kind

    p = Path(path)
    if p.is_dir():
        files = sorted((f for f in p.iterdir() if f.suffix.lower() in (".png", ".jpg", ".jpeg")), key=natural_key)
    else:
        files = [p]
    out = []
    for f in files:
        if (kind := special_file_kind(f)) is not None:  # cv2.imread of a FIFO blocks until someone writes
            raise SourceError(f"background image {f}: is a {kind}; expected a no-contact frame image file")
        img = cv2.imread(str(f), cv2.IMREAD_COLOR)
        if img is None:
            raise SourceError(f"background image {f}: missing or not decodable (expected a no-contact frame)")
        fitted = fit_frame(img, FRAME_SHAPE)
        if fitted is None:
            raise SourceError(f"background image {f}: {img.shape[0]}x{img.shape[1]} pixels (rows x cols); expected "
                              f"a {FRAME_SHAPE[0]}x{FRAME_SHAPE[1]} no-contact frame of the same sensor as the frames "
                              f"(or its {FRAME_SHAPE[1]}x{FRAME_SHAPE[0]} landscape view)")
        out.append(fitted)
    if not out:
        raise SourceError(f"background folder {p}: no .png/.jpg images")
    return out
