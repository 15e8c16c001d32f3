"""Indenter catalogue of the virtual DIGIT: the paper's 18 flat indenters plus spheres,
cylinders and everyday-like objects.

Every indenter is described in its own frame in millimetres: ``gap_mm(x, y)`` is the height
of its tip surface above its lowest point (0 on a flat face, r^2/2R-like on a sphere) and
``inf`` where the indenter has no material. Flat shapes are polygons rasterised with OpenCV.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

#: Contact-mechanics law used for an indenter kind (see mechanics.py).
KINDS = ("flat", "sphere", "profile")
#: The paper's object rigidity groups (Medium / High / Very High).
STIFFNESS_CLASSES = ("medium", "high", "very_high")
#: The nine paper-like flat shapes, each at two scales -> 18 indenters.
PAPER_SHAPES = ("square", "star", "arrow", "circle", "triangle", "hexagon", "cross", "ellipse", "crescent")
#: Outer size (mm, across) of the two scales of the paper-like indenters.
PAPER_SCALES_MM = {"small": 4.5, "large": 7.0}


@dataclass(frozen=True, slots=True)
class Indenter:
    """One indenter.

    name: unique id ('star_large'); shape: geometry family; kind: 'flat' (flat-punch law),
    'sphere' (Hertz), 'profile' (per-pixel penalty model); size_mm: outer size across
    (flat) or radius (sphere, cylinder); scale: 'small'/'large' for the paper set, else
    'object'; length_mm: cylinder length; stiffness: default rigidity class; textured:
    3D-print layer ridges on the face; paper: one of the paper's 18.
    """

    name: str
    shape: str
    kind: str
    size_mm: float
    scale: str = "object"
    length_mm: float = 0.0
    stiffness: str = "very_high"
    textured: bool = False
    paper: bool = False

    @property
    def extent_mm(self) -> float:
        """Half-width (mm) of a box that holds the footprint (capped by the caller to the pad)."""
        if self.shape == "sphere":
            return self.size_mm
        if self.shape == "cylinder":
            return max(self.size_mm, self.length_mm / 2.0)
        return self.size_mm / 2.0 * 1.05

    def polygon_mm(self) -> np.ndarray:
        """Outline (K x 2, mm, x right / y down, centred) of a flat indenter."""
        r = self.size_mm / 2.0
        s = self.shape
        if s == "square":
            pts = [(-r, -r), (r, -r), (r, r), (-r, r)]  # side = size
        elif s in ("circle", "ellipse", "ring"):
            t = np.linspace(0, 2 * np.pi, 72, endpoint=False)
            ry = r * (0.6 if s == "ellipse" else 1.0)
            return np.stack([r * np.cos(t), ry * np.sin(t)], 1)
        elif s == "triangle":
            pts = [(r * math.cos(a), r * math.sin(a)) for a in np.deg2rad([-90, 30, 150])]
        elif s == "hexagon":
            pts = [(r * math.cos(a), r * math.sin(a)) for a in np.deg2rad(np.arange(0, 360, 60))]
        elif s == "star":
            pts = []
            for k in range(10):
                rr = r if k % 2 == 0 else 0.42 * r
                a = math.radians(-90 + 36 * k)
                pts.append((rr * math.cos(a), rr * math.sin(a)))
        elif s == "cross":
            w = r / 3.0
            pts = [(-w, -r), (w, -r), (w, -w), (r, -w), (r, w), (w, w), (w, r), (-w, r), (-w, w), (-r, w),
                   (-r, -w), (-w, -w)]
        elif s == "arrow":
            pts = [(0, -r), (r, 0), (0.35 * r, 0), (0.35 * r, r), (-0.35 * r, r), (-0.35 * r, 0), (-r, 0)]
        elif s == "crescent":
            t = np.linspace(-np.pi / 2, np.pi / 2, 36)
            outer = np.stack([r * np.cos(t), r * np.sin(t)], 1)  # right half circle, top -> bottom
            inner = np.stack([0.35 * r * np.cos(t[::-1]), r * np.sin(t[::-1])], 1)  # shallower arc back
            return np.concatenate([outer, inner]) - [0.3 * r, 0]
        elif s == "rounded_square":
            t = np.linspace(0, 2 * np.pi, 72, endpoint=False)
            n = 8.0  # superellipse exponent: a die's rounded square face
            c, si = np.cos(t), np.sin(t)
            return np.stack([r * np.sign(c) * np.abs(c) ** (2 / n), r * np.sign(si) * np.abs(si) ** (2 / n)], 1)
        else:
            raise ValueError(f"indenter {self.name!r}: shape {s!r} has no polygon outline")
        return np.asarray(pts, dtype=np.float64)

    def gap_mm(self, x: np.ndarray, y: np.ndarray, ppm: float, texture_phase: float = 0.0) -> np.ndarray:
        """Tip height (mm) above the lowest point at local coordinates x, y (mm); inf off the body.

        ppm: pixels per mm of the grid x, y were sampled on (for polygon rasterisation).
        """
        if self.shape == "sphere":
            r2 = x * x + y * y
            rr = self.size_mm * self.size_mm
            out = np.full(x.shape, np.inf, np.float32)
            ok = r2 < rr
            out[ok] = self.size_mm - np.sqrt(rr - r2[ok])
            return out
        if self.shape == "cylinder":
            rr = self.size_mm * self.size_mm
            out = np.full(x.shape, np.inf, np.float32)
            ok = (y * y < rr) & (np.abs(x) <= self.length_mm / 2.0)
            out[ok] = self.size_mm - np.sqrt(rr - y[ok] ** 2)
            return out
        mask = self._polygon_mask(x, y, ppm)
        out = np.full(x.shape, np.inf, np.float32)
        if self.textured:
            # 3D-print layer ridges: 0.55 mm pitch, 0.012 mm deep, along the local y axis.
            ridges = 0.006 * (1.0 + np.sin(2 * np.pi * x / 0.55 + texture_phase))
            out[mask] = ridges[mask]
        else:
            out[mask] = 0.0
        return out

    def _polygon_mask(self, x: np.ndarray, y: np.ndarray, ppm: float) -> np.ndarray:
        """Boolean footprint on the grid (x, y are a rotated pixel grid in mm).

        The polygon is tested in local coordinates with a point-in-polygon raster: the grid is
        mapped back to pixel units of an axis-aligned canvas, so rotation is exact.
        """
        poly = self.polygon_mm()
        if self.shape == "ring":
            inner = np.hypot(x, y) < self.size_mm / 2.0 * 0.7
        # Rasterise the local polygon once on a local canvas at 4x the pixel density.
        k = 4.0 * ppm
        half = int(math.ceil(self.size_mm / 2.0 * 1.1 * k)) + 2
        canvas = np.zeros((2 * half + 1, 2 * half + 1), np.uint8)
        pts = np.round((poly * k + half) * 16).astype(np.int32)
        cv2.fillPoly(canvas, [pts], 1, lineType=cv2.LINE_8, shift=4)
        ci = np.round(y * k + half).astype(np.int64)
        cj = np.round(x * k + half).astype(np.int64)
        inside = (ci >= 0) & (ci < canvas.shape[0]) & (cj >= 0) & (cj < canvas.shape[1])
        mask = np.zeros(x.shape, bool)
        mask[inside] = canvas[ci[inside], cj[inside]] > 0
        if self.shape == "ring":
            mask &= ~inner
        return mask


def _paper_indenters() -> list[Indenter]:
    out = []
    for scale, size in PAPER_SCALES_MM.items():
        for shape in PAPER_SHAPES:
            out.append(Indenter(f"{shape}_{scale}", shape, "flat", size, scale=scale, stiffness="very_high",
                                textured=True, paper=True))
    return out


#: The paper-like set (18 = 9 shapes x 2 scales), in a fixed order used by the splits.
PAPER_INDENTERS: tuple[Indenter, ...] = tuple(_paper_indenters())

#: Spheres, cylinders and everyday-like objects (sizes and rigidity from the paper's Table of
#: everyday objects where they fit; radii in mm).
EXTRA_INDENTERS: tuple[Indenter, ...] = (
    Indenter("ball_2.35mm", "sphere", "sphere", 2.35, stiffness="very_high"),  # calibration ball
    Indenter("sphere_4mm", "sphere", "sphere", 4.0, stiffness="very_high"),
    Indenter("marble", "sphere", "sphere", 10.5, stiffness="very_high"),
    Indenter("strawberry", "sphere", "sphere", 22.0, stiffness="high"),
    Indenter("peach", "sphere", "sphere", 29.0, stiffness="high"),
    Indenter("soccer_ball", "sphere", "sphere", 46.0, stiffness="high"),
    Indenter("green_toy", "sphere", "sphere", 38.0, stiffness="medium"),
    Indenter("pen", "cylinder", "profile", 4.5, length_mm=40.0, stiffness="high"),
    Indenter("cylinder_8mm", "cylinder", "profile", 8.0, length_mm=40.0, stiffness="very_high"),
    Indenter("cup", "cylinder", "profile", 40.0, length_mm=100.0, stiffness="very_high"),
    Indenter("pringles", "cylinder", "profile", 37.0, length_mm=200.0, stiffness="medium"),
    Indenter("dice", "rounded_square", "flat", 16.0, stiffness="very_high"),
    Indenter("rubiks_cube", "square", "flat", 56.0, stiffness="high"),
    Indenter("bottle_cap", "ring", "flat", 9.0, stiffness="high"),
)

INDENTERS: dict[str, Indenter] = {i.name: i for i in PAPER_INDENTERS + EXTRA_INDENTERS}


def get_indenter(name: str | Indenter) -> Indenter:
    """Look an indenter up by name; ValueError listing the known names otherwise."""
    if isinstance(name, Indenter):
        return name
    try:
        return INDENTERS[name]
    except KeyError:
        raise ValueError(f"unknown indenter {name!r}; known: {', '.join(INDENTERS)}") from None


def paper_indenter_names() -> list[str]:
    """Names of the 18 paper-like indenters, in catalogue order."""
    return [i.name for i in PAPER_INDENTERS]
