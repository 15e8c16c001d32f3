"""Per-sensor force calibration: a monotone map from a model's raw estimate to newtons.

Stored in a bundle's manifest (``force_calibration``) and applied by the runtime to every
model output (:meth:`ForceCalibration.apply_inplace`: a binary search over a few knots per
value, no allocation). Fitting is :mod:`tactile_force.edge.fitting.force_calibration`
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
class SensorFingerprint:
    """Which sensor a calibration was fitted on: its serial when known, and a fingerprint of
    its no-contact look that tells two DIGIT units (or a real unit from a simulated one) apart.

    thumb: the no-contact frame's colours on a thumb_rows x thumb_cols grid (INTER_AREA, one
        cell = 16 x 16 pixels of a 320 x 240 frame; row-major, then B, G, R; grey levels).
    texture: per channel (B, G, R) the fine texture of the frame: mean |frame - 5x5 Gaussian
        blur of it| over its channel's mean brightness (gel texture and camera noise; a
        rendered frame's synthetic noise differs from a real camera's).
    source: what the fingerprint was made from (``--background FILE`` or the lightest press;
        ``from_press`` True then: the thumbnail holds a light press).
    A frame matches when at least ``min_fit`` of its cells fit the thumbnail within
    ``fit_tolerance`` grey levels after a per-channel gain and offset (LED drift allowed), and
    its texture is within a factor ``texture_ratio`` of the fingerprint's on every channel.
    """

    serial: str = ""
    source: str = ""
    thumb_rows: int = 20
    thumb_cols: int = 15
    thumb: list[float] = field(default_factory=list)
    texture: list[float] = field(default_factory=list)
    from_press: bool = False
    min_fit: float = 0.5
    fit_tolerance: float = 8.0
    texture_ratio: float = 1.35

    def check(self) -> None:
        """Raise ValueError naming the first field that does not fit the others."""
        if self.thumb and len(self.thumb) != self.thumb_rows * self.thumb_cols * 3:
            raise ValueError(f"force_calibration.sensor.thumb: {len(self.thumb)} values; expected thumb_rows x "
                             f"thumb_cols x 3 = {self.thumb_rows * self.thumb_cols * 3}")
        if self.texture and len(self.texture) != 3:
            raise ValueError(f"force_calibration.sensor.texture: {len(self.texture)} values; expected 3 (B, G, R)")
        if not (0 < self.min_fit < 1 and self.fit_tolerance > 0 and self.texture_ratio > 1):
            raise ValueError("force_calibration.sensor: expected 0 < min_fit < 1, fit_tolerance > 0, texture_ratio > 1")


def _look(frame_bgr: np.ndarray, rows: int, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """(thumbnail rows x cols x 3 float64, texture (3,)) of an HxWx3 uint8 BGR frame."""
    import cv2  # lazily: this module stays numpy-only on import

    f = np.asarray(frame_bgr)
    thumb = cv2.resize(f, (cols, rows), interpolation=cv2.INTER_AREA).astype(np.float64)
    ff = f.astype(np.float32)
    detail = np.abs(ff - cv2.GaussianBlur(ff, (5, 5), 0)).reshape(-1, 3).mean(axis=0)
    level = np.maximum(ff.reshape(-1, 3).mean(axis=0), 1.0)
    return thumb, (detail / level).astype(np.float64)


def cells_fitting(ref_thumb, thumb: np.ndarray, tolerance: float = 8.0) -> np.ndarray:
    """Which thumbnail cells of ``thumb`` (rows x cols x 3) fit ``ref_thumb`` (the same grid,
    any shape holding rows x cols x 3 values) within ``tolerance`` grey levels on every channel
    after a per-channel gain and offset, fitted robustly on the cells that fit (a press or a
    blob does not pull the fit). Returns a bool array (rows, cols)."""
    x = np.asarray(ref_thumb, np.float64).reshape(-1, 3)
    y = np.asarray(thumb, np.float64).reshape(-1, 3)
    keep = np.ones(len(x), bool)
    res = np.zeros(len(x))
    for _ in range(4):
        xs, ys = x[keep], y[keep]
        var = xs.var(axis=0)
        gain = np.where(var > 1e-3, ((xs * ys).mean(axis=0) - xs.mean(axis=0) * ys.mean(axis=0))
                        / np.maximum(var, 1e-3), 0.0)
        off = ys.mean(axis=0) - gain * xs.mean(axis=0)
        res = np.abs(y - (x * gain + off)).max(axis=1)
        new = res < tolerance
        if new.sum() < len(x) // 4:
            break
        keep = new
    return (res < tolerance).reshape(np.asarray(thumb).shape[:2])


def look(frame_bgr: np.ndarray) -> np.ndarray:
    """The frame's colours on the fingerprint grid (one cell = 16 x 16 pixels), float64."""
    return _look(frame_bgr, max(2, frame_bgr.shape[0] // 16), max(2, frame_bgr.shape[1] // 16))[0]


def sensor_fingerprint(frame_bgr: np.ndarray, serial: str = "", source: str = "") -> SensorFingerprint:
    """The fingerprint of a no-contact frame (HxWx3 uint8 BGR, 320 x 240 for a DIGIT)."""
    rows, cols = max(2, frame_bgr.shape[0] // 16), max(2, frame_bgr.shape[1] // 16)
    thumb, texture = _look(frame_bgr, rows, cols)
    return SensorFingerprint(serial=serial, source=source, thumb_rows=rows, thumb_cols=cols,
                             thumb=[round(float(v), 2) for v in thumb.ravel()],
                             texture=[round(float(v), 5) for v in texture])


def fingerprint_mismatch(fp: SensorFingerprint, frame_bgr: np.ndarray, serial: str = "") -> str:
    """Why ``frame_bgr`` (a no-contact frame of the sensor in use, HxWx3 uint8 BGR) does not
    come from the sensor ``fp`` describes, or "" when it does (or cannot be told).

    serial: the sensor's serial when its source knows it (a known, equal serial matches)."""
    who = f"sensor {fp.serial}" if fp.serial else f"the sensor of {fp.source or 'the calibration'}"
    if serial and fp.serial:
        return "" if serial == fp.serial else (f"this bundle's force calibration was fitted on sensor {fp.serial}, "
                                               f"not on {serial}")
    if not fp.thumb or frame_bgr.shape[0] // 16 != fp.thumb_rows or frame_bgr.shape[1] // 16 != fp.thumb_cols:
        return ""
    thumb, texture = _look(frame_bgr, fp.thumb_rows, fp.thumb_cols)
    fit = float(np.mean(cells_fitting(fp.thumb, thumb, fp.fit_tolerance)))
    if fit < fp.min_fit:
        return (f"this bundle's force calibration was fitted on another sensor ({who}): only {100 * fit:.0f} % of "
                "this sensor's no-contact image fits the calibration's (re-run calibrate-force on this sensor)")
    if fp.texture:
        ratio = texture / np.maximum(np.asarray(fp.texture, np.float64), 1e-9)
        worst = float(ratio.max() if ratio.max() >= 1 / ratio.min() else ratio.min())
        if not 1 / fp.texture_ratio <= worst <= fp.texture_ratio:
            return (f"this bundle's force calibration was fitted on another sensor ({who}): the image's fine "
                    f"texture is x{worst:.2f} the calibration's (another camera, or a simulated sensor; re-run "
                    "calibrate-force on this sensor)")
    return ""


@dataclass
class ForceCalibration:
    """Piecewise-linear monotone map raw estimate (N) -> calibrated force (N).

    ``raw_n`` are strictly increasing knots of the model's raw output, ``force_n`` the
    non-decreasing calibrated force (N) at each knot. The first and last segments are the
    linear extrapolation made at fit time (to 0 N below and past 15 N above); outside the
    knots the output is held at the end value. ``model_sha256`` is the sha256 of the ONNX
    model the map was fitted for (the runtime refuses it on another model).
    ``loo_before`` / ``loo_after``: leave-one-out error of the raw and the calibrated
    estimate on the calibration frames. ``sensor``: the sensor it was fitted on (serial,
    no-contact fingerprint; None in calibrations written before it existed): the runtime flags
    readings from another sensor ``out_of_distribution``.
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
    sensor: SensorFingerprint | None = None

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
        rng = self.force_range_n
        if rng and (len(rng) != 2 or not 0 <= rng[0] <= rng[1]):
            raise ValueError(f"force_calibration.force_range_n {rng}: expected [low, high] with 0 <= low <= high (N)")
        if self.frames < 0:
            raise ValueError(f"force_calibration.frames {self.frames}: expected >= 0")
        if self.sensor is not None:
            self.sensor.check()
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
