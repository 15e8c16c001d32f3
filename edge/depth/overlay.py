"""A contact sheet of the ball presses with their contact circles drawn, for the user to
check what ``calibrate-depth`` fitted on.

Each press is one tile (scaled to ``tile_width`` pixels wide): the circle in green for a
press used in the fit, in orange for a held-out press, and a red cross over a press where
no circle was found (skipped). The press name is written in the tile's corner.
"""

from __future__ import annotations

import enum
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .calibration import Circle


class PressRole(str, enum.Enum):
    FIT = "fit"
    HELDOUT = "held out"
    SKIPPED = "no circle"


#: BGR colour of each role.
ROLE_COLOUR = {PressRole.FIT: (0, 200, 0), PressRole.HELDOUT: (0, 140, 255), PressRole.SKIPPED: (0, 0, 255)}


@dataclass(frozen=True, slots=True)
class PressTile:
    """One press for the sheet: frame HxWx3 uint8 BGR, its circle (pixels; None when not found)."""

    frame: np.ndarray
    circle: Circle | None
    name: str
    role: PressRole


def _tile(t: PressTile, width: int) -> np.ndarray:
    h, w = t.frame.shape[:2]
    scale = width / w
    img = cv2.resize(t.frame, (width, max(1, round(h * scale))), interpolation=cv2.INTER_AREA)
    colour = ROLE_COLOUR[t.role]
    if t.circle is not None:
        c = t.circle
        centre = (round(c.cx * scale), round(c.cy * scale))
        cv2.circle(img, centre, max(1, round(c.r * scale)), colour, 2, cv2.LINE_AA)
        cv2.drawMarker(img, centre, colour, cv2.MARKER_CROSS, 8, 1, cv2.LINE_AA)
    else:
        cv2.line(img, (0, 0), (img.shape[1] - 1, img.shape[0] - 1), colour, 2, cv2.LINE_AA)
        cv2.line(img, (0, img.shape[0] - 1), (img.shape[1] - 1, 0), colour, 2, cv2.LINE_AA)
    name = t.name if len(t.name) <= 20 else ".." + t.name[-18:]
    label = f"{name} ({t.role.value})"
    (tw, th), _ = cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, 0.4, 1)
    cv2.rectangle(img, (0, 0), (min(img.shape[1] - 1, tw + 8), th + 8), (0, 0, 0), cv2.FILLED)
    cv2.putText(img, label, (4, th + 4), cv2.FONT_HERSHEY_SIMPLEX, 0.4, colour, 1, cv2.LINE_AA)
    return img


def circle_sheet(tiles: list[PressTile], tile_width: int = 240, columns: int = 6) -> np.ndarray:
    """The contact sheet, HxWx3 uint8 BGR: ``columns`` tiles per row, 4-pixel gaps."""
    if not tiles:
        raise ValueError("circle sheet: no presses to draw")
    imgs = [_tile(t, tile_width) for t in tiles]
    th = max(i.shape[0] for i in imgs)
    cols = min(columns, len(imgs))
    rows = -(-len(imgs) // cols)
    gap = 4
    sheet = np.full((rows * (th + gap) - gap, cols * (tile_width + gap) - gap, 3), 40, np.uint8)
    for k, img in enumerate(imgs):
        r, c = divmod(k, cols)
        y, x = r * (th + gap), c * (tile_width + gap)
        sheet[y:y + img.shape[0], x:x + img.shape[1]] = img
    return sheet


def write_image(path: str | os.PathLike, img: np.ndarray) -> Path:
    """Write an image atomically (temp file in the same folder, then rename); the format
    follows the suffix (.png, .jpg). ValueError when OpenCV cannot encode it."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    ok, buf = cv2.imencode(out.suffix or ".png", img)
    if not ok:
        raise ValueError(f"{out}: OpenCV cannot write this image format (use .png or .jpg)")
    fd, tmp = tempfile.mkstemp(prefix=out.name + ".", suffix=".tmp", dir=out.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(buf.tobytes())
        os.replace(tmp, out)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return out
