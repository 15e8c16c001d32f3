"""Real-vs-synthetic montage for the docs.

    python -m tactile_force.edge.synthetic.montage ../shared/data/aurova_digit_grasp docs/synthetic_vs_real.png

Row 1: real AUROVA DIGIT grasp frames (authors' layout) at five forces; row 2: the virtual
DIGIT pressing a 7 mm disc with the same forces; row 3: other indenters at 8 N.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import cv2
import numpy as np

from ..data.dataset import AuthorsDataset
from .digit import ContactSpec, VirtualDigit, VirtualDigitOptions


def _label(img: np.ndarray, text: str) -> np.ndarray:
    out = img.copy()
    cv2.putText(out, text, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (255, 255, 255), 1, cv2.LINE_AA)
    return out


def make_montage(real_dir: str | os.PathLike, out_path: str | os.PathLike, seed: int = 0) -> Path:
    """Write the montage PNG; returns its path."""
    ds = AuthorsDataset(real_dir)
    picks = [ds.ids[i] for i in np.linspace(0, len(ds) - 1, 5).round().astype(int)]
    real = [ds.load(n) for n in picks]
    digit = VirtualDigit(VirtualDigitOptions(seed=seed))
    row1 = [_label(s.frame, f"real {s.force_n:.1f} N") for s in real]
    row2 = [_label(digit.render(ContactSpec("circle_large", (150.0, 135.0)), s.force_n).frame,
                   f"synth {s.force_n:.1f} N") for s in real]
    others = [("star_large", (160.0, 120.0)), ("ball_2.35mm", (170.0, 110.0)), ("cross_small", (150.0, 130.0)),
              ("pen", (160.0, 120.0)), ("hexagon_large", (20.0, 120.0))]
    row3 = [_label(digit.render(ContactSpec(n, c, rotation_deg=20.0), 8.0).frame, f"{n} 8 N") for n, c in others]
    img = np.vstack([np.hstack(row1), np.hstack(row2), np.hstack(row3)])
    out = Path(out_path)
    out.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(out), img)
    return out


if __name__ == "__main__":  # pragma: no cover
    if len(sys.argv) != 3:
        sys.exit("usage: python -m tactile_force.edge.synthetic.montage REAL_DATASET_DIR OUT.png")
    print(make_montage(sys.argv[1], sys.argv[2]))
