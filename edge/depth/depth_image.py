"""Height map -> the paper's 8-bit depth image (H x W x 1 uint8, 0 outside the contact mask).

Two modes:

* exact: ``depth = clip(height_px * levels_per_px, 0, 255)`` inside the mask, 0 outside.
* paper-compatible (what the authors' D-type checkpoints were trained on): their
  digit-depth pipeline integrates *undecoded* MLP output into a "distance from the gel"
  map (metres, negative where pressed), subtracts a zero-depth reference (mean of the
  first 50 frames), multiplies by 255 and by -1, and thresholds to zero
  (``cv2.THRESH_TOZERO``); the contact mask then zeroes the background. ``paper_scale``
  is the total factor from metres to 8-bit levels (255 x their x255 ... see docs/depth.md).
"""

from __future__ import annotations

import numpy as np


def exact_depth_image(height: np.ndarray, mask: np.ndarray, levels_per_px: float, out: np.ndarray) -> np.ndarray:
    """height: H x W float (px of indentation); mask: H x W bool, or 0/1 float32 (the same
    image, without a cast per pixel); out: H x W x 1 uint8."""
    o = out[..., 0]
    scaled = np.multiply(height, levels_per_px, dtype=np.float32)
    np.maximum(scaled, 0.0, out=scaled)
    np.minimum(scaled, 255.0, out=scaled)
    np.multiply(scaled, mask, out=scaled)  # 0 outside the mask (values >= 0: no -0.0)
    np.rint(scaled, out=scaled)
    o[...] = scaled
    return out


def paper_depth_image(distance: np.ndarray, reference: np.ndarray, mask: np.ndarray, paper_scale: float,
                      out: np.ndarray) -> np.ndarray:
    """distance, reference: H x W float (metres, the authors' integrated map and its
    zero-depth mean); returns out H x W x 1 uint8 = clip(-(distance - reference) * scale)."""
    o = out[..., 0]
    diff = np.subtract(reference, distance, dtype=np.float32)  # the sign flip: pressed -> positive
    diff *= paper_scale
    np.clip(diff, 0.0, 255.0, out=diff)  # THRESH_TOZERO, then the 8-bit range
    diff[~mask] = 0.0
    np.rint(diff, out=diff)
    o[...] = diff
    return out
