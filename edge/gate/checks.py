"""The contact gate's judging checks (edge/gate/contact_gate.py, ``ContactGate``): pure functions over the
gate's preallocated thumbnail buffers (rows x cols x 3 float32, one cell = 16 x 16 frame
pixels), each a handful of OpenCV/numpy calls; the gate composes them in its judging and
decides from their answers (docs/runtime.md, "Flags").

- :class:`Reference`: what the checks need of the background thumbnail (its cells, the
  dark level, the shift/rotation basis), re-made lazily when the background is refreshed;
- :func:`dark_share` (occlusion), :func:`colour_swapped` (RGB order),
  :func:`motion_explained` (gel/camera moved), :func:`borders_changed` (mismatch borders),
  :func:`is_uniform` (no gel image), :func:`noise_verdict` (noise burst, blurred frame).
"""

from __future__ import annotations

import cv2
import numpy as np

_ALL_SET = (255, 255, 255)


class Reference:
    """What the trust checks need of a background thumbnail (N cells x 3, float32): the
    cells, their squares, and (lazily) the shift/rotation basis of its gradients."""

    def __init__(self, thumb: np.ndarray) -> None:
        self.rows, self.cols = thumb.shape[:2]
        self.x = thumb.reshape(-1, 3)  # a view: follows the refreshed background thumbnail
        self._motion: tuple[np.ndarray, np.ndarray] | None = None
        self._dark: np.ndarray | None = None
        # cell coordinates about the centre (they do not change with the background)
        yy, xx = np.mgrid[: self.rows, : self.cols].astype(np.float32)
        yy -= self.rows / 2.0
        xx -= self.cols / 2.0
        self._yy, self._xx = yy[..., None], xx[..., None]

    def refreshed(self) -> None:
        """The background thumbnail changed: the motion basis and the dark level are made
        again when next needed."""
        self._motion = None
        self._dark = None

    def dark(self) -> np.ndarray:
        """45 % of the background + 2 grey levels per cell and channel (rows x cols x 3,
        float32): under it on every channel, a cell is dark."""
        if self._dark is None:
            self._dark = (0.45 * self.x + 2.0).reshape(self.rows, self.cols, 3)
        return self._dark

    def motion(self) -> tuple[np.ndarray, np.ndarray]:
        """(pinv (3, 3N), G^T G (3, 3)) of the basis d(thumb)/d(shift x, shift y, rotation)."""
        if self._motion is None:
            t = self.x.reshape(self.rows, self.cols, 3)
            gx = cv2.Sobel(t, cv2.CV_32F, 1, 0, ksize=3) / 8.0
            gy = cv2.Sobel(t, cv2.CV_32F, 0, 1, ksize=3) / 8.0
            rot = (-self._yy * gx + self._xx * gy) / max(self.rows, self.cols)
            g = np.stack([gx.ravel(), gy.ravel(), rot.ravel()], axis=1).astype(np.float64)
            self._motion = (np.linalg.pinv(g).astype(np.float32), (g.T @ g).astype(np.float32))
        return self._motion


def dark_share(thumb: np.ndarray, dark: np.ndarray, cmp_buf: np.ndarray, dark_buf: np.ndarray) -> float:
    """Share of thumbnail cells where every channel fell below the background's dark level
    (a contact shifts colours; it does not black out the gel).

    Parameters
    ----------
    thumb : np.ndarray
        The frame's thumbnail, rows x cols x 3 float32.
    dark : np.ndarray
        :meth:`Reference.dark` (rows x cols x 3 float32).
    cmp_buf, dark_buf : np.ndarray
        Preallocated rows x cols x 3 and rows x cols uint8 buffers (overwritten).

    Returns
    -------
    float
        0..1.
    """
    cv2.compare(thumb, dark, cv2.CMP_LT, dst=cmp_buf)
    cv2.inRange(cmp_buf, _ALL_SET, _ALL_SET, dst=dark_buf)
    return cv2.countNonZero(dark_buf) / float(dark_buf.size)


def colour_swapped(y: np.ndarray, x: np.ndarray, fit_tolerance: float, fit_frac: float) -> bool:
    """True when B and R swapped fit the background far better than the frame as it is.

    Parameters
    ----------
    y, x : np.ndarray
        The frame's and the background's thumbnail cells, N x 3 float32 (B, G, R).
    fit_tolerance : float
        A cell fits when its residual after a per-channel gain/offset fit is below this on
        every channel (grey levels; ``GateOptions.fit_tolerance``).
    fit_frac : float
        The share of cells that fit the frame as it is (0..1).

    Returns
    -------
    bool
        At least 40 % of the cells, and 30 points more than as it is, fit with B and R swapped.
    """
    ys = np.ascontiguousarray(y[:, ::-1])
    n = float(len(ys))
    sx, sy, sxx, sxy = x.sum(0), ys.sum(0), (x * x).sum(0), (x * ys).sum(0)
    den = n * sxx - sx * sx
    gain = (n * sxy - sx * sy) / np.maximum(den, 1e-3)
    off = (sy - gain * sx) / n
    frac = float(np.mean(np.abs(ys - (x * gain + off)).max(axis=1) < fit_tolerance))
    return frac >= max(0.4, fit_frac + 0.3)


def motion_explained(thumb: np.ndarray, model: np.ndarray, residual: np.ndarray, ref: Reference) -> float:
    """Share of the residual energy a shift/rotation of the background explains.

    Parameters
    ----------
    thumb : np.ndarray
        The frame's thumbnail, rows x cols x 3 float32.
    model : np.ndarray
        The background's thumbnail after the photometric fit (same shape).
    residual : np.ndarray
        A preallocated buffer of the same shape (overwritten with ``thumb - model``).
    ref : Reference
        The background's reference (its motion basis).

    Returns
    -------
    float
        0..1 (0 when the rms residual is under 2 grey levels: nothing to explain).
    """
    cv2.subtract(thumb, model, dst=residual)
    energy = cv2.norm(residual, cv2.NORM_L2SQR)
    if energy < residual.size * 4.0:  # rms residual under 2 grey levels: nothing to explain
        return 0.0
    pinv, gtg = ref.motion()
    d = pinv @ residual.reshape(-1)
    return float(d @ gtg @ d) / energy


def borders_changed(inliers: np.ndarray) -> int:
    """How many of the four border strips (2 thumbnail cells wide) mostly do not fit.

    Parameters
    ----------
    inliers : np.ndarray
        rows x cols uint8, non-zero where the cell fits the background.

    Returns
    -------
    int
        0..4.
    """
    bad = inliers == 0
    strips = (bad[:2], bad[-2:], bad[:, :2], bad[:, -2:])
    return sum(1 for s in strips if s.mean() > 0.5)


def is_uniform(thumb: np.ndarray) -> bool:
    """True when the thumbnail (rows x cols x 3 float32) has no gel image: every channel's
    spread over the cells is under 2 grey levels."""
    return float(cv2.meanStdDev(thumb)[1].max()) < 2.0


def noise_verdict(noise: float, bg_noise: float, gain: list[float], noise_factor: float) -> tuple[bool, str]:
    """The frame's pixel-noise level against the background's.

    Parameters
    ----------
    noise, bg_noise : float
        Pixel-noise level (mean |frame - blurred frame|, grey levels) of the frame and of the
        background.
    gain : list of float
        The fitted per-channel (B, G, R) gain of the frame against the background.
    noise_factor : float
        ``GateOptions.noise_factor``.

    Returns
    -------
    tuple of (bool, str)
        (a noise burst: above ``noise_factor`` x the background's level (scaled by the largest
        gain above 1) + 1 grey level; why the frame is invalid: the burst, or a blurred frame
        (under 45 % of the background's fine detail, scaled by the smallest gain below 1),
        "" otherwise).
    """
    if noise > noise_factor * bg_noise * max(1.0, *gain) + 1.0:
        return True, (f"noise burst: pixel noise {noise:.1f} grey levels against {bg_noise:.1f} in the "
                      "background (interference, a failing cable or camera?)")
    if noise < 0.45 * bg_noise * min(1.0, *gain):
        return False, (f"blurred frame: fine detail {noise:.1f} grey levels against {bg_noise:.1f} in the "
                       "background (defocus, a smudged lens or condensation?)")
    return False, ""
