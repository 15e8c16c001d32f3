"""Surface normals -> height gradients, with guards.

Sign conventions (used everywhere in edge/depth):

* image axes: x along columns (right), y along rows (down), z toward the camera;
* height ``h`` >= 0 is the indentation of the gel toward the camera (pixels of height);
* a normal ``n = (nx, ny, nz)`` is the unit normal of the gel surface pointing toward the
  camera (nz > 0 on a usable surface). For the surface z = h(x, y) that normal is
  ``(-h_x, -h_y, 1) / norm``, so ``h_x = -nx / nz`` and ``h_y = -ny / nz``.
  Example: a ball pressed at (cx, cy) gives ``n = (x - cx, y - cy, sqrt(R^2 - r^2)) / R``,
  h_x = -(x - cx)/sqrt(R^2 - r^2): the height falls away from the centre.

Guards: nz is floored at ``nz_min`` (n_z -> 0 would give infinite slopes), slopes are
clamped to +-``max_slope`` (the gel's curved edge), NaN/inf become 0 (flat).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..checks import check_fields
from ..typed_json import check


@dataclass(frozen=True, slots=True)
class GradientGuards:
    """nz_min: floor of n_z (unitless, > 0); max_slope: |dh/dx|, |dh/dy| clamp (px/px)."""

    nz_min: float = field(default=0.1, metadata=check(gt=0, le=1))
    max_slope: float = field(default=4.0, metadata=check(gt=0))

    def __post_init__(self) -> None:
        check_fields(self)


def normals_to_gradients(
    normals: np.ndarray,
    guards: GradientGuards = GradientGuards(),
    out: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, int]:
    """(..., 3) normals (nx, ny, nz) -> (gx, gy, n_clamped).

    gx = dh/dx (along columns), gy = dh/dy (along rows), in height per pixel; n_clamped
    counts elements that were non-finite or hit a guard. ``out`` reuses two float arrays
    of shape normals.shape[:-1].
    """
    n = np.asarray(normals)
    if n.shape[-1] != 3:
        raise ValueError(f"normals shape {n.shape}: expected (..., 3) = (nx, ny, nz)")
    if out is None:
        gx = np.empty(n.shape[:-1], dtype=np.float32)
        gy = np.empty(n.shape[:-1], dtype=np.float32)
    else:
        gx, gy = out
    nz = np.maximum(n[..., 2], guards.nz_min)  # NaN -> NaN (handled below)
    np.divide(n[..., 0], nz, out=gx, casting="unsafe")
    np.divide(n[..., 1], nz, out=gy, casting="unsafe")
    np.negative(gx, out=gx)
    np.negative(gy, out=gy)
    bad = int(np.count_nonzero(n[..., 2] < guards.nz_min))
    for g in (gx, gy):
        finite = np.isfinite(g)
        if not finite.all():
            bad += int(g.size - np.count_nonzero(finite))
            g[~finite] = 0.0
        over = np.abs(g) > guards.max_slope
        if over.any():
            bad += int(np.count_nonzero(over))
            np.clip(g, -guards.max_slope, guards.max_slope, out=g)
    return gx, gy, bad
