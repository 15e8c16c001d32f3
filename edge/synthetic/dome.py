"""The DIGIT gel dome: a parametric height map (mm) of the undeformed pad.

The DIGIT elastomer is not flat: it is highest near the middle and falls off towards the
edges (about 0.84 mm peak, about 0.1 mm at the corners). A quadratic bowl
``h = peak - a*u^2 - b*v^2`` (u, v normalised column/row offsets) fits the measured FOTS pad
within about 0.1 mm; indenters touching near the edges therefore make partial contact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..checks import check_fields


@dataclass(frozen=True, slots=True)
class DomeOptions:
    """Dome shape: peak height (mm), drops (mm) to the left/right and top/bottom border,
    and the centre and half-extents in pixels of the 320 x 240 frame."""

    peak_mm: float = 0.84
    drop_cols_mm: float = 0.55
    drop_rows_mm: float = 0.30
    center_row: float = 140.0
    center_col: float = 120.0
    half_rows: float = 160.0
    half_cols: float = 120.0

    def __post_init__(self) -> None:
        check_fields(self)

def dome_height_mm(shape: tuple[int, int] = (320, 240), options: DomeOptions = DomeOptions()) -> np.ndarray:
    """Height of the undeformed gel (rows x cols float32, mm, >= 0)."""
    rows, cols = shape
    v = (np.arange(rows, dtype=np.float32)[:, None] - options.center_row) / options.half_rows
    u = (np.arange(cols, dtype=np.float32)[None, :] - options.center_col) / options.half_cols
    h = options.peak_mm - options.drop_cols_mm * u * u - options.drop_rows_mm * v * v
    return np.maximum(h, 0.0).astype(np.float32)
