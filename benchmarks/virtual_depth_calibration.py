"""Calibrate the depth stage for the virtual DIGIT, the way a user calibrates a real one.

Renders ball presses (radius 2.35 mm, as the FOTS/AUROVA calibration ball) with the
virtual DIGIT, writes them as PNGs with a no-contact background, and runs the same
``tactile-force calibrate-depth`` a user runs on real presses. The result ships as
edge/assets/virtual_digit_depth.npz: the depth stage's mapping for synthetic frames,
used to make the depth images the reference D / Dmod / RGBmod+D models train on.

    python -m benchmarks.virtual_depth_calibration
"""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

from .harness.frames import VIRTUAL_DEPTH_MAPPING

BALL_MM = 2.35


def render_presses(folder: Path, n: int = 40, seed: int = 0) -> Path:
    """n ball presses at random places and depths, plus background.png; returns folder."""
    digit = VirtualDigit(VirtualDigitOptions(seed=seed))
    rng = np.random.default_rng(seed)
    presses = folder / "presses"
    presses.mkdir(parents=True, exist_ok=True)
    for i in range(n):
        center = (float(rng.uniform(70, 250)), float(rng.uniform(55, 185)))
        shot = digit.render_ball_press(center, BALL_MM, float(rng.uniform(0.5, 1.2)), led_gain=(1.0, 1.0, 1.0), rng=rng)
        cv2.imwrite(str(presses / f"{i:04d}.png"), shot.frame)
    cv2.imwrite(str(folder / "background.png"), digit.render(None, 0.0, led_gain=(1.0, 1.0, 1.0), rng=rng).frame)
    return folder


def main() -> int:
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        folder = render_presses(Path(tmp))
        px_per_mm = VirtualDigitOptions().px_per_mm
        return cli_main(["calibrate-depth", str(folder / "presses"), "--background", str(folder / "background.png"),
                         "--ball-radius-mm", str(BALL_MM), "--px-per-mm", str(px_per_mm),
                         "-o", str(VIRTUAL_DEPTH_MAPPING)])


if __name__ == "__main__":
    sys.exit(main())
