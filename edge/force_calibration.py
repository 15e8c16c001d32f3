"""Per-sensor force calibration: a monotone map from a model's raw estimate to newtons.

Stored in a bundle's manifest (``force_calibration``) and applied by the runtime to every
model output (:meth:`ForceCalibration.apply_inplace`: a binary search over a few knots per
value, no allocation). Fitting is :mod:`tactile_force.edge.calibrate_force`
(``tactile-force calibrate-force``); this module only holds the record and applies it
(numpy only, so ``import tactile_force.edge`` stays light).
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np


@dataclass
class CalibrationFigures:
    """Leave-one-out error on the calibration frames: RE (dimensionless) and MAE (N), mean +- std."""

    re_mean: float
    re_std: float
    mae_mean: float
    mae_std: float
    frames: int


@dataclass
class ForceCalibration:
    """Piecewise-linear monotone map raw estimate (N) -> calibrated force (N).

    ``raw_n`` are strictly increasing knots of the model's raw output, ``force_n`` the
    non-decreasing calibrated force (N) at each knot. The first and last segments are the
    linear extrapolation made at fit time (to 0 N below and past 15 N above); outside the
    knots the output is held at the end value. ``model_sha256`` is the sha256 of the ONNX
    model the map was fitted for (the runtime refuses it on another model).
    ``loo_before`` / ``loo_after``: leave-one-out error of the raw and the calibrated
    estimate on the calibration frames.
    """

    raw_n: list[float]
    force_n: list[float]
    method: str = "isotonic"
    frames: int = 0
    data: str = ""
    force_range_n: list[float] = field(default_factory=list)
    spearman: float | None = None
    model_sha256: str = ""
    loo_before: CalibrationFigures | None = None
    loo_after: CalibrationFigures | None = None

    def __post_init__(self) -> None:
        try:  # invalid knots are reported by check() (typed_json calls it after construction)
            self._cache()
        except (ValueError, TypeError):
            pass

    def check(self) -> None:
        """Raise ValueError (naming the field) unless the knots describe a monotone map."""
        r, f = np.asarray(self.raw_n, np.float64), np.asarray(self.force_n, np.float64)
        if r.ndim != 1 or r.size < 2 or r.size != f.size:
            raise ValueError(f"force_calibration.raw_n / force_n: need the same length >= 2, got {r.size} and {f.size}")
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(f))):
            raise ValueError("force_calibration.raw_n / force_n: knots must be finite numbers")
        if np.any(np.diff(r) <= 0):
            raise ValueError("force_calibration.raw_n: knots must be strictly increasing")
        if np.any(np.diff(f) < 0):
            raise ValueError("force_calibration.force_n: must be non-decreasing (a force calibration is monotone)")
        self._cache()

    def _cache(self) -> None:
        r, f = np.asarray(self.raw_n, np.float64), np.asarray(self.force_n, np.float64)
        # cached for the hot path (plain attributes, not dataclass fields: never serialised)
        self._r = r
        self._f = f
        self._rl = [float(v) for v in r]
        self._fl = [float(v) for v in f]
        self._slope = [float(v) for v in np.diff(f) / np.diff(r)]

    def apply(self, raw: np.ndarray) -> np.ndarray:
        """Calibrated forces (N) for raw estimates ``raw`` (any shape), float32 (a new array).

        NaN stays NaN (an invalid estimate must stay invalid)."""
        x = np.asarray(raw, np.float64)
        y = np.where(np.isnan(x), np.nan, np.interp(x, self._r, self._f))
        return np.asarray(y, np.float32)

    def apply_inplace(self, values: np.ndarray) -> np.ndarray:
        """Calibrate the 1-D float array ``values`` (N) in place and return it.

        For the runtime's 1-2 values per call: a bisect per value, no array allocation."""
        rl, fl, sl = self._rl, self._fl, self._slope
        last = len(rl) - 1
        for i in range(values.shape[0]):
            x = float(values[i])
            if math.isnan(x):  # NaN stays NaN
                continue
            if x <= rl[0]:
                values[i] = fl[0]
            elif x >= rl[last]:
                values[i] = fl[last]
            else:
                k = bisect.bisect_right(rl, x) - 1
                values[i] = fl[k] + (x - rl[k]) * sl[k]
        return values
