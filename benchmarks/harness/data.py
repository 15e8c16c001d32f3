"""Readers of the shared real sensor data (:func:`~.paths.shared_data`; its README says what
each recording is) and of labelled frames as arrays.

- :func:`digit_backgrounds`: the four real DIGIT units' no-contact frames;
- :func:`aurova` / :func:`real_frames`: the labelled AUROVA DIGIT grasp (11 frames, and its
  held-out half);
- :func:`wedge_frames` / :func:`wedge_grasps`: GelSight Wedge grasps as a user would feed them
  to a DIGIT bundle (another sensor type);
- :class:`Labelled` and :func:`predict_all`: labelled frames and a model's forces on them.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from .paths import SetupError, shared_data

#: The GelSight Wedge gel warped to this size (px) from its raw 640x480 view.
WEDGE_WARP = (400, 300)
#: Pixels cropped per edge of the warped Wedge view.
WEDGE_CROP = 25


@dataclass
class Labelled:
    """rgb (N,320,240,3) uint8 BGR, depth (N,320,240,1) uint8 or None, force (N,) N, source."""

    rgb: np.ndarray
    depth: np.ndarray | None
    force: np.ndarray
    source: str


def predict_all(model, data: Labelled) -> np.ndarray:
    """(N,) forces from an OnnxForceModel (batches of 2, its maximum)."""
    out = np.empty(len(data.force), np.float64)
    for i in range(0, len(out), 2):
        rgb = data.rgb[i:i + 2] if model.rgb_name else None
        d = data.depth[i:i + 2] if model.needs_depth and data.depth is not None else None
        out[i:i + 2] = model.predict(rgb, d)
    return out


def real_frames(root: Path | None = None) -> Labelled | None:
    """The 11 labelled real AUROVA DIGIT frames (``root``, default the shared
    aurova_digit_grasp; depth = the paper's filtered depth images); None if absent."""
    root = root or shared_data("aurova_digit_grasp")
    if not (root / "images").is_dir():
        return None
    from tactile_force.edge import AuthorsDataset

    ds = AuthorsDataset(root)
    samples = [ds.load(n) for n in ds.ids]
    depth = None
    if all(s.depth is not None for s in samples):
        depth = np.stack([s.depth.reshape(320, 240, 1) for s in samples])
    return Labelled(np.stack([s.frame for s in samples]), depth, np.array([s.force_n for s in samples]),
                    f"real AUROVA DIGIT frames ({len(samples)})")


def _img(*parts: str) -> np.ndarray:
    p = shared_data(*parts)
    img = cv2.imread(str(p))
    if img is None:
        raise SetupError(f"{p}: missing (the shared sensor data; set $TACTILE_FORCE_SHARED_DATA to its folder)")
    return img


def digit_backgrounds() -> dict[str, np.ndarray]:
    """The four real DIGIT units' no-contact frames (320x240 BGR), by file stem."""
    folder = shared_data("digit_backgrounds")
    return {p.stem: _img("digit_backgrounds", p.name) for p in sorted(folder.iterdir())
            if p.suffix in (".png", ".jpg")}


def aurova(heldout: bool = False) -> list[tuple[np.ndarray, float]]:
    """(frame, force N) of the shared AUROVA grasp (or its held-out half), paired by number."""
    from tactile_force.edge.data.dataset import AuthorsDataset  # the package's one labelled-data reader

    return [(s.frame, float(s.force_n)) for s in
            AuthorsDataset(shared_data("aurova_digit_grasp_heldout" if heldout else "aurova_digit_grasp"))]


def wedge_frames(video: Path) -> list[np.ndarray]:
    """Frames of one GelSight Wedge grasp video (``ROOT/example_data/DATE/NAME.avi``) as a user
    would feed them to a DIGIT bundle: the raw view warped with the 4 gel corners of
    ``ROOT/wedge_config/config_100.csv`` to 400x300, 25 px cropped per edge, turned portrait
    and resized to 320x240 (INTER_AREA), HxWx3 uint8 BGR; frame 0 has no contact."""
    root = video.parents[2]
    corners = {}
    for line in (root / "wedge_config" / "config_100.csv").read_text().splitlines()[1:]:
        name, x, y = line.split(",")
        corners[name.strip()] = (float(x), float(y))
    src = np.array([corners[k] for k in ("topleft", "topright", "bottomleft", "bottomright")], np.float32)
    w, h = WEDGE_WARP
    dst = np.array([[0, 0], [w, 0], [0, h], [w, h]], np.float32)
    warp = cv2.getPerspectiveTransform(src, dst)
    cap = cv2.VideoCapture(str(video))
    frames = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        g = cv2.warpPerspective(f, warp, (w, h))[WEDGE_CROP:-WEDGE_CROP, WEDGE_CROP:-WEDGE_CROP]
        frames.append(cv2.resize(cv2.rotate(g, cv2.ROTATE_90_CLOCKWISE), (240, 320), interpolation=cv2.INTER_AREA))
    cap.release()
    return frames


def wedge_grasps(every: int = 1) -> list[tuple[str, list[np.ndarray], list[float]]]:
    """Every GelSight Wedge grasp (:func:`wedge_frames`): (name, frames, forces N)."""
    out = []
    for video in sorted(shared_data("gelsight_wedge_grasps", "example_data").glob("*/*.avi")):
        forces = [float(v) for v in video.with_name(video.stem + "_forces.csv").read_text().split()]
        frames = wedge_frames(video)
        n = min(len(frames), len(forces))
        out.append((f"{video.parent.name}/{video.stem}", frames[:n:every], forces[:n:every]))
    return out
