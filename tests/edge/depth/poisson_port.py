"""The Poisson solve widely copied across digit-depth / PyTouch / tactile-in-hand, restated for
comparison with the depth stage's exact solver (test_depth_poisson.py; the timing: docs/depth_benchmark.md)."""

from __future__ import annotations

import numpy as np


def port_solve(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """The widely copied port, re-stated for comparison: interior (H-2) x (W-2) with a zero
    frame ring, orthonormal DST-II forward / DST-III inverse, eigenvalues pi k/(n+2)."""
    import scipy.fft as sfft

    h, w = gx.shape
    f = np.zeros((h, w))
    f[:-1, 1:] += gx[:-1, 1:] - gx[:-1, :-1]
    f[1:, :-1] += gy[1:, :-1] - gy[:-1, :-1]
    f = f[1:-1, 1:-1]
    spec = sfft.dstn(f, type=2, norm="ortho", workers=1)
    ky = np.arange(1, f.shape[0] + 1)[:, None]
    kx = np.arange(1, f.shape[1] + 1)[None, :]
    denom = (2 * np.cos(np.pi * kx / (f.shape[1] + 2)) - 2) + (2 * np.cos(np.pi * ky / (f.shape[0] + 2)) - 2)
    out = np.zeros((h, w))
    out[1:-1, 1:-1] = sfft.idstn(spec / denom, type=2, norm="ortho", workers=1)
    return out
