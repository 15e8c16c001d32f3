"""Shading of the virtual DIGIT: gel deformation (mm) -> colour change (BGR, 0..255 units).

Analytic model: the DIGIT lights its gel with three coloured LEDs from three sides. A
surface patch tilted towards an LED reflects more of its colour, one tilted away less, and
steep walls at the contact edge are in shadow for all of them. With slope vector
g = grad(height) (mm/mm) and LED azimuth u_i in the image plane, the change of channel c is

    dI_c = w_c(x, y) * [ sum_i S_i col_ic s0 tanh(g.u_i / s0) - shadow_c s0 tanh(|g| / s0)
                         + press_c * height ] + flatten * min(1, height / h0) * (smooth_bg_c - bg_c)

w_c is the background's own channel brightness (LEDs fade across the pad). Azimuths and
strengths were fitted by least squares to a real AUROVA DIGIT grasp (frame minus the
background, against the gradients of its filtered depth image): blue rises on walls facing
down the image, green on walls facing left, red on walls facing up-right. Where the gel is
pressed flat against the object the background's LED pattern washes out towards its local
mean (the ``flatten`` term, as in the real grasp frames).

Optional: the FOTS normal-to-colour MLP (a user-supplied .npz, never shipped).
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import cv2
import numpy as np

from ..checks import check_fields


@dataclass(frozen=True, slots=True)
class Led:
    """One LED: azimuth (degrees, image plane, x right / y down: the slope direction that
    brightens it), strength (0..255 units per unit slope) and colour (B, G, R weights)."""

    azimuth_deg: float
    strength: float
    colour_bgr: tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class ShadingOptions:
    """Analytic shading constants (see module docstring)."""

    leds: tuple[Led, ...] = (
        Led(-98.0, 380.0, (1.0, 0.15, 0.05)),   # blue: walls whose height falls towards the bottom
        Led(-15.0, 140.0, (0.05, 1.0, 0.1)),     # green
        Led(155.0, 190.0, (0.05, 0.1, 1.0)),    # red
    )
    shadow_bgr: tuple[float, float, float] = (40.0, 100.0, 20.0)
    press_bgr: tuple[float, float, float] = (-15.0, 5.0, 5.0)
    press_flatten: float = 0.6
    press_flatten_mm: float = 0.3
    slope_scale: float = 0.35

    def __post_init__(self) -> None:
        check_fields(self)

class AnalyticShader:
    """Colour change of a deformation patch with the three-LED model."""

    def __init__(self, background: np.ndarray, px_per_mm: float, options: ShadingOptions = ShadingOptions()):
        bg = background.astype(np.float32)
        self.weight = np.clip(bg / bg.reshape(-1, 3).mean(0), 0.5, 1.6).astype(np.float32)
        self.flatten_to = (cv2.GaussianBlur(bg, (0, 0), 20.0) - bg).astype(np.float32)
        self.px_per_mm = float(px_per_mm)
        self.options = options
        # Per-channel linear maps: response_c = sum_i a_ic * s0 tanh((gx cos_i + gy sin_i)/s0).
        self._dirs = [(np.cos(np.deg2rad(l.azimuth_deg)), np.sin(np.deg2rad(l.azimuth_deg))) for l in options.leds]
        self._gain = np.array([[l.strength * c for c in l.colour_bgr] for l in options.leds], np.float32)

    def delta(self, height_mm: np.ndarray, r0: int, c0: int) -> np.ndarray:
        """Colour change (h x w x 3 float32, BGR) of a height patch whose top-left is (r0, c0)."""
        o = self.options
        s0 = o.slope_scale
        k = self.px_per_mm / 8.0  # Sobel 3x3 sums 8 x the per-pixel difference
        gx = cv2.Sobel(height_mm, cv2.CV_32F, 1, 0, ksize=3) * k
        gy = cv2.Sobel(height_mm, cv2.CV_32F, 0, 1, ksize=3) * k
        out = np.empty(height_mm.shape + (3,), np.float32)
        mag = s0 * np.tanh(np.sqrt(gx * gx + gy * gy) / s0)
        resp = [s0 * np.tanh((gx * cx + gy * cy) / s0) for cx, cy in self._dirs]
        for c in range(3):
            acc = -o.shadow_bgr[c] * mag + o.press_bgr[c] * height_mm
            for i, r in enumerate(resp):
                if self._gain[i, c]:
                    acc += self._gain[i, c] * r
            out[..., c] = acc
        h, w = height_mm.shape
        out *= self.weight[r0:r0 + h, c0:c0 + w]
        if o.press_flatten:
            t = np.minimum(height_mm * (o.press_flatten / o.press_flatten_mm), o.press_flatten)
            out += t[..., None] * self.flatten_to[r0:r0 + h, c0:c0 + w]
        return out


class MlpShader:
    """FOTS normal-to-colour MLP (5-32-32-32-3; ReLU after fc1 and fc2 only).

    Per pixel input (col/240, row/320, n'), n' = (n + 1)/2, n = normalise(dz/dcol, -dz/drow, 1)
    from the height map in pixels; colour change = 255 * (MLP(n) - MLP(flat)).
    """

    def __init__(self, path: str | os.PathLike, px_per_mm: float, frame_shape=(320, 240)):
        from ..errors import TactileForceError

        try:
            z = np.load(path)
            self.w = [z[f"fc{i}_weight"].astype(np.float32) for i in range(1, 5)]
            self.b = [z[f"fc{i}_bias"].astype(np.float32) for i in range(1, 5)]
        except (OSError, KeyError, ValueError) as exc:
            raise TactileForceError(
                f"{path}: not a normal-to-colour MLP .npz with fc1_weight..fc4_bias ({exc})") from None
        if self.w[0].shape != (32, 5) or self.w[3].shape != (3, 32):
            raise TactileForceError(f"{path}: MLP layer shapes {[w.shape for w in self.w]}; expected 5-32-32-32-3")
        self.px_per_mm = float(px_per_mm)
        self.rows, self.cols = frame_shape

    def _mlp(self, x: np.ndarray) -> np.ndarray:
        h = np.maximum(x @ self.w[0].T + self.b[0], 0)
        h = np.maximum(h @ self.w[1].T + self.b[1], 0)
        h = h @ self.w[2].T + self.b[2]
        return h @ self.w[3].T + self.b[3]

    def delta(self, height_mm: np.ndarray, r0: int, c0: int) -> np.ndarray:
        z = height_mm * self.px_per_mm
        dzr, dzc = np.gradient(z)
        n = np.stack([dzc, -dzr, np.ones_like(z)], -1)
        n /= np.linalg.norm(n, axis=-1, keepdims=True)
        h, w = z.shape
        rr, cc = np.mgrid[r0:r0 + h, c0:c0 + w].astype(np.float32)
        pos = np.stack([cc / self.cols, rr / self.rows], -1)
        x = np.concatenate([pos, (n + 1) / 2], -1).reshape(-1, 5).astype(np.float32)
        flat = x.copy()
        flat[:, 2:] = (0.5, 0.5, 1.0)
        d = 255.0 * (self._mlp(x) - self._mlp(flat))
        return d.reshape(h, w, 3)[..., ::-1].astype(np.float32)  # MLP gives RGB -> BGR
