"""Colour -> normal calibration from ball presses: circle detection, sphere normals and a
lookup table (LUT) on the colour difference to a no-contact background.

Calibration file (our own .npz, loaded by :class:`NormalLUT.load`):
``format`` = "tactile_force.depth_lut", ``version`` = 1, ``lut`` (B, B, B, 3) float32 unit
normals indexed by the quantised BGR difference, ``bin_width`` (intensity levels per bin),
``background`` (H x W x 3 uint8 BGR), ``px_per_mm``, ``ball_radius_mm``, ``report`` (JSON
text of the held-out evaluation).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from ..checks import check_fields, expect
from .normals import MappingError, _load_npz

LUT_FORMAT = "tactile_force.depth_lut"
LUT_VERSION = 1


@dataclass(frozen=True, slots=True)
class Circle:
    """A contact circle: centre (cx = column, cy = row) and radius r, pixels."""

    cx: float
    cy: float
    r: float


@dataclass(frozen=True, slots=True)
class Press:
    """One ball press: frame H x W x 3 uint8 BGR and its contact circle (None: detect it)."""

    frame: np.ndarray
    circle: Circle | None = None
    name: str = ""


def detect_press_circle(frame: np.ndarray, background: np.ndarray, min_radius_px: float = 4.0) -> Circle | None:
    """Find a ball's contact circle without clicking.

    The colour difference to the background is blurred, thresholded (Otsu, at least 6
    levels), cleaned, and the largest blob's area and centroid give the circle
    (r = sqrt(area / pi)). Returns None when no blob of at least ``min_radius_px`` exists.
    """
    diff = cv2.absdiff(frame, background).astype(np.float32).sum(axis=2)
    sigma = max(1.0, min(frame.shape[:2]) / 160.0)
    diff = cv2.GaussianBlur(diff, (0, 0), sigma)
    d8 = np.clip(diff, 0, 255).astype(np.uint8)
    thr, _ = cv2.threshold(d8, 0, 255, cv2.THRESH_BINARY + cv2.THRESH_OTSU)
    thr = max(thr, 6.0 * 3)
    mask = (diff > thr).astype(np.uint8)
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, k)
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, k, iterations=2)
    n, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    if n <= 1:
        return None
    i = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    # Fill holes of the blob (the centre of a press can be close to the background colour).
    blob = (labels == i).astype(np.uint8)
    contours, _ = cv2.findContours(blob, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    c = max(contours, key=cv2.contourArea)
    area = cv2.contourArea(c)
    r = float(np.sqrt(area / np.pi))
    if r < min_radius_px:
        return None
    m = cv2.moments(c)
    return Circle(cx=float(m["m10"] / m["m00"]), cy=float(m["m01"] / m["m00"]), r=r)


#: Median detected contact radius / ball radius (pixels) accepted by :func:`check_circle_scale`.
#: Below 0.15 the press would be under 1.2 % of the ball radius deep (r^2 ~ 2 R d), too shallow
#: to see; above 1.6 the contact circle is larger than the ball (detection reads real presses
#: up to about 1.3 times the true contact radius: the gel bulges around the ball).
CIRCLE_TO_BALL_RANGE = (0.15, 1.6)


def check_circle_scale(circles: list[Circle], frame_shape: tuple[int, int], ball_radius_mm: float,
                       px_per_mm: float, see: str = "") -> float:
    """Check that contact circles fit a ball of ``ball_radius_mm`` at ``px_per_mm``.

    Parameters
    ----------
    circles : detected (or given) contact circles, pixels.
    frame_shape : (rows, cols) of the frames, pixels.
    ball_radius_mm : the calibration ball's radius, mm (finite, > 0).
    px_per_mm : image scale, pixels per mm (finite, > 0).
    see : where the circles can be looked at (the circle image), for the message.

    Returns
    -------
    float : the ball radius in pixels, ``ball_radius_mm * px_per_mm``.

    Raises
    ------
    DatasetError : a radius or scale that is not a finite number > 0, a ball larger than the
        frame, or circles whose median radius is outside :data:`CIRCLE_TO_BALL_RANGE` times
        the ball's radius in pixels (a wrong ``--px-per-mm`` or ``--ball-radius-mm``).
    """
    from ..errors import DatasetError

    for flag, v in (("--ball-radius-mm", ball_radius_mm), ("--px-per-mm", px_per_mm)):
        if not (np.isfinite(v) and v > 0):
            raise DatasetError(f"{flag} {v}: expected a finite number > 0")
    ball_px = float(ball_radius_mm * px_per_mm)
    rows, cols = int(frame_shape[0]), int(frame_shape[1])
    where = f" (circles drawn in {see})" if see else ""
    if ball_px > max(rows, cols):
        raise DatasetError(
            f"--ball-radius-mm {ball_radius_mm:g} at --px-per-mm {px_per_mm:g} is a ball {ball_px:.0f} px in radius, "
            f"larger than the {rows}x{cols} frame: expected the image scale in pixels per mm of these frames "
            f"(e.g. 19.6 for a DIGIT) and the ball's radius (not its diameter) in mm")
    if not circles:
        return ball_px
    med = float(np.median([c.r for c in circles]))
    lo, hi = CIRCLE_TO_BALL_RANGE
    ratio = med / ball_px
    if ratio > hi:
        raise DatasetError(
            f"the contact circles (median radius {med:.1f} px) are {ratio:.1f} times the ball's radius of "
            f"{ball_px:.1f} px (--ball-radius-mm {ball_radius_mm:g} x --px-per-mm {px_per_mm:g}): a contact circle "
            f"cannot be larger than the ball; --px-per-mm or --ball-radius-mm is too small{where}")
    if ratio < lo:
        raise DatasetError(
            f"the contact circles (median radius {med:.1f} px) are only {ratio:.2f} times the ball's radius of "
            f"{ball_px:.1f} px (--ball-radius-mm {ball_radius_mm:g} x --px-per-mm {px_per_mm:g}): presses that "
            f"shallow are not visible; --px-per-mm or --ball-radius-mm is too large (expected circles of "
            f"{lo:g} to {hi:g} times the ball radius){where}")
    return ball_px


def sphere_normals(shape: tuple[int, int], circle: Circle,
                   ball_radius_px: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Normals and heights of a ball of radius R px pressed with contact ``circle``.

    Returns (normals H x W x 3 float32, inside H x W bool, height H x W float32 px):
    inside the circle n = (x - cx, y - cy, sqrt(R^2 - r^2)) / R (y down, toward camera),
    height = sqrt(R^2 - r^2) - sqrt(R^2 - rc^2); outside (0, 0, 1) and 0.
    """
    h, w = shape
    rows, cols = np.mgrid[0:h, 0:w].astype(np.float32)
    dx = cols - circle.cx
    dy = rows - circle.cy
    r2 = dx * dx + dy * dy
    rc = min(circle.r, ball_radius_px * 0.999)
    inside = r2 < rc * rc
    R = float(ball_radius_px)
    nz = np.sqrt(np.maximum(R * R - r2, 0.0))
    n = np.zeros((h, w, 3), dtype=np.float32)
    n[..., 2] = 1.0
    n[inside, 0] = dx[inside] / R
    n[inside, 1] = dy[inside] / R
    n[inside, 2] = nz[inside] / R
    height = np.where(inside, nz - np.sqrt(R * R - rc * rc), 0.0).astype(np.float32)
    return n, inside, height


def cap_depth_px(circle_r_px: float, ball_radius_px: float) -> float:
    """Depth of a spherical cap with contact radius rc: R - sqrt(R^2 - rc^2), pixels."""
    rc = min(circle_r_px, ball_radius_px)
    return float(ball_radius_px - np.sqrt(ball_radius_px ** 2 - rc ** 2))


@dataclass(slots=True)
class LUTOptions:
    """bins: table size per colour channel; bin_width: intensity levels per bin (the table
    covers +-bins*bin_width/2 around the background); background_margin: pixels farther
    than margin * r from the centre are used as flat (0, 0, 1) samples; background_stride:
    subsampling of those flat samples."""

    bins: int = 32
    bin_width: float = 6.0
    background_margin: float = 1.4
    background_stride: int = 7

    def __post_init__(self) -> None:
        check_fields(self)

@dataclass(slots=True)
class AngleError:
    """Angle between predicted and true normals inside contact circles, degrees."""

    mean_deg: float
    median_deg: float
    p90_deg: float
    pixels: int


class NormalLUT:
    """Colour difference -> unit normal lookup table.

    ``normals(frame, index)`` -> (N, 3) float32 normals for flat pixel indices ``index``
    of an H x W x 3 uint8 BGR frame (same size as the stored background).
    """

    def __init__(self, lut: np.ndarray, bin_width: float, background: np.ndarray,
                 px_per_mm: float = float("nan"), ball_radius_mm: float = float("nan"),
                 report: dict | None = None) -> None:
        expect(lut, np.ndarray, "NormalLUT.lut", "a (B, B, B, 3) float array of unit normals")
        expect(bin_width, float, "NormalLUT.bin_width", "a colour bin width > 0 (grey levels)", gt=0)
        expect(background, np.ndarray, "NormalLUT.background", "an H x W x 3 uint8 BGR no-contact frame")
        b = lut.shape[0]
        if lut.ndim != 4 or lut.shape != (b, b, b, 3):
            raise MappingError(f"LUT shape {lut.shape}: expected (B, B, B, 3)")
        if not np.all(np.isfinite(lut)):
            raise MappingError("LUT holds NaN or inf (corrupted calibration file)")
        if background.ndim != 3 or background.shape[2] != 3 or background.dtype != np.uint8:
            raise MappingError(f"LUT background {background.shape} {background.dtype}: expected H x W x 3 uint8 BGR")
        self.lut = np.ascontiguousarray(lut, dtype=np.float32)
        self.flat_lut = self.lut.reshape(-1, 3)
        self.bins = b
        self.bin_width = float(bin_width)
        self.px_per_mm = float(px_per_mm)
        self.ball_radius_mm = float(ball_radius_mm)
        self.report = report or {}
        self.set_background(background)

    def set_background(self, background: np.ndarray) -> None:
        """Replace the no-contact reference frame (H x W x 3 uint8 BGR)."""
        self.background = np.ascontiguousarray(background)
        # Offset so that q = floor((frame - bg + offset) / width) is centred on the zero difference.
        self._bg_shifted = (self.background.astype(np.float32).reshape(-1, 3) - self.bins * self.bin_width / 2.0)

    def index(self, frame: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
        """Flat LUT cell index of each selected pixel (N,) int."""
        pix = frame.reshape(-1, 3)
        bg = self._bg_shifted
        if idx is not None:
            pix = pix[idx]
            bg = bg[idx]
        q = (pix.astype(np.float32) - bg)
        q *= 1.0 / self.bin_width
        np.clip(q, 0, self.bins - 1, out=q)
        qi = q.astype(np.intp)
        return (qi[:, 0] * self.bins + qi[:, 1]) * self.bins + qi[:, 2]

    def normals(self, frame: np.ndarray, idx: np.ndarray | None = None) -> np.ndarray:
        return self.flat_lut[self.index(frame, idx)]

    # ----------------------------------------------------------------- persistence
    def save(self, path: str | os.PathLike) -> Path:
        p = Path(path)
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp = p.with_name(f".{p.name}.tmp.npz")
        np.savez_compressed(tmp, format=np.array(LUT_FORMAT), version=np.array(LUT_VERSION), lut=self.lut,
                            bin_width=np.array(self.bin_width), background=self.background,
                            px_per_mm=np.array(self.px_per_mm), ball_radius_mm=np.array(self.ball_radius_mm),
                            report=np.array(json.dumps(self.report)))
        os.replace(tmp, p)
        return p

    @classmethod
    def from_arrays(cls, z: dict[str, np.ndarray], source: str = "<arrays>") -> NormalLUT:
        if str(z.get("format", "")) != LUT_FORMAT:
            raise MappingError(f"{source}: not a calibrate-depth file (format {z.get('format')!r}, "
                               f"expected {LUT_FORMAT!r})")
        if int(z["version"]) != LUT_VERSION:
            raise MappingError(f"{source}: calibration version {int(z['version'])}; this package reads {LUT_VERSION}")
        try:
            return cls(z["lut"], float(z["bin_width"]), z["background"], float(z["px_per_mm"]),
                       float(z["ball_radius_mm"]), json.loads(str(z["report"])))
        except KeyError as exc:
            raise MappingError(f"{source}: calibration file lacks {exc}") from None

    @classmethod
    def load(cls, path: str | os.PathLike) -> NormalLUT:
        return cls.from_arrays(_load_npz(path), str(path))


def _fill_empty(sums: np.ndarray, counts: np.ndarray, max_iter: int = 64) -> np.ndarray:
    """Mean normal per cell; empty cells take the mean of filled 6-neighbours, repeatedly."""
    filled = counts > 0
    lut = np.zeros_like(sums)
    lut[filled] = sums[filled] / counts[filled, None]
    for _ in range(max_iter):
        if filled.all():
            break
        acc = np.zeros_like(lut)
        cnt = np.zeros(filled.shape, dtype=np.float32)
        for ax in range(3):
            for sh in (1, -1):
                src_f = np.roll(filled, sh, axis=ax)
                src_v = np.roll(lut, sh, axis=ax)
                # no wrap-around
                sl = [slice(None)] * 3
                sl[ax] = slice(0, 1) if sh == 1 else slice(-1, None)
                src_f[tuple(sl)] = False
                acc += np.where(src_f[..., None], src_v, 0.0)
                cnt += src_f
        new = (~filled) & (cnt > 0)
        lut[new] = acc[new] / cnt[new, None]
        filled = filled | new
    lut[~filled] = (0.0, 0.0, 1.0)
    norm = np.linalg.norm(lut, axis=-1, keepdims=True)
    return (lut / np.maximum(norm, 1e-6)).astype(np.float32)


def fit_lut(presses: list[Press], background: np.ndarray, ball_radius_px: float,
            options: LUTOptions | None = None) -> NormalLUT:
    """Fit a LUT from presses with known circles (detect missing ones first)."""
    options = options or LUTOptions()
    b = options.bins
    sums = np.zeros((b, b, b, 3), dtype=np.float64)
    counts = np.zeros((b, b, b), dtype=np.float64)
    proto = NormalLUT(np.zeros((b, b, b, 3), np.float32), options.bin_width, background)
    h, w = background.shape[:2]
    rows, cols = np.mgrid[0:h, 0:w]
    for press in presses:
        if press.circle is None:
            raise ValueError(f"press {press.name!r} has no circle; detect it first")
        n, inside, _ = sphere_normals((h, w), press.circle, ball_radius_px)
        far = np.hypot(cols - press.circle.cx, rows - press.circle.cy) > options.background_margin * press.circle.r
        far &= ((rows + cols) % options.background_stride) == 0
        sel = np.flatnonzero((inside | far).ravel())
        cell = proto.index(press.frame, sel)
        np.add.at(sums.reshape(-1, 3), cell, n.reshape(-1, 3)[sel])
        np.add.at(counts.reshape(-1), cell, 1.0)
    lut = _fill_empty(sums.astype(np.float32), counts.astype(np.float32))
    return NormalLUT(lut, options.bin_width, background)


def angle_error(pred: np.ndarray, true: np.ndarray) -> np.ndarray:
    """Angles between (N, 3) normal sets, degrees."""
    p = pred / np.maximum(np.linalg.norm(pred, axis=1, keepdims=True), 1e-9)
    t = true / np.maximum(np.linalg.norm(true, axis=1, keepdims=True), 1e-9)
    return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", p, t), -1.0, 1.0)))


def evaluate_lut(lut: NormalLUT, presses: list[Press], ball_radius_px: float) -> AngleError:
    """Normal angle error of ``lut`` inside the contact circles of ``presses``."""
    errs = []
    for press in presses:
        if press.circle is None:  # no contact circle: nothing to compare against
            continue
        n, inside, _ = sphere_normals(press.frame.shape[:2], press.circle, ball_radius_px)
        idx = np.flatnonzero(inside.ravel())
        errs.append(angle_error(lut.normals(press.frame, idx), n.reshape(-1, 3)[idx]))
    e = np.concatenate(errs) if errs else np.zeros(0)
    if e.size == 0:
        return AngleError(float("nan"), float("nan"), float("nan"), 0)
    return AngleError(float(e.mean()), float(np.median(e)), float(np.percentile(e, 90)), int(e.size))
