"""Forces of a bundle on labelled frames (synthetic held-out split, real AUROVA frames)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .frames import REPO

REAL_DIR = REPO.parent / "shared" / "data" / "aurova_digit_grasp"


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
        d = data.depth[i:i + 2] if model.needs_depth else None
        out[i:i + 2] = model.predict(rgb, d)
    return out


def synthetic_test(with_depth: bool) -> Labelled:
    """The held-out-indenter test split of the reference dataset (benchmarks.reference)."""
    from . import reference

    arrays = reference.load_arrays(reference.ensure_dataset(), with_depth=with_depth)
    idx = arrays.select("test")
    return Labelled(arrays.rgb[idx], arrays.depth[idx] if with_depth else None, arrays.force[idx].astype(np.float64),
                    f"synthetic test split ({reference.SPLIT}, held-out indenters, {len(idx)} frames)")


def real_frames(root: Path = REAL_DIR) -> Labelled | None:
    """The 11 labelled real AUROVA DIGIT frames (depth = the paper's filtered depth images); None if absent."""
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
