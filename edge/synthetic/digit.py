"""The virtual DIGIT: contact spec + normal force (N) -> 320 x 240 BGR frame with ground truth.

Pipeline per frame: indenter tip geometry on the gel dome (mm) -> contact law gives the
indentation depth for the force (mechanics.py) -> gel deformation = the gel's share of the
penetration, faded below ~1 N, with an elastic skirt around the contact -> shading
(three-LED analytic model or the FOTS MLP) -> camera blur -> real no-contact background
x LED gain + sensor noise.

Scale: ``px_per_mm`` = 19.58 (the FOTS DIGIT calibration; DIGITs are about 17-20 px/mm),
so the 320 x 240 frame spans about 16.3 x 12.3 mm.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from ..checks import check_fields, expect
from ..errors import FrameError
from ..frames import FRAME_COLS, FRAME_ROWS, check_frame
from ..typed_json import check
from .dome import DomeOptions, dome_height_mm
from .indenters import Indenter, get_indenter
from .mechanics import (
    GelOptions,
    combined_modulus,
    flat_punch_depth,
    gel_force,
    hertz_depth,
    hertz_force,
    onset_visibility,
    penalty_depth,
)
from .shading import AnalyticShader, MlpShader, ShadingOptions

#: The shipped no-contact background (AUROVA-LAB/aurova_grasping, MIT; see assets/).
DEFAULT_BACKGROUND = Path(__file__).resolve().parents[1] / "assets" / "digit_background.png"


@dataclass(frozen=True, slots=True)
class VirtualDigitOptions:
    """Options of the virtual DIGIT.

    px_per_mm: image scale (pixels per mm of gel); background: no-contact frame
    (320x240 BGR image file; None = the shipped one); noise_std_bgr: per-channel sensor noise
    (0..255 units, measured on real DIGIT frames); blur_px: camera defocus (Gaussian sigma,
    px); skirt_mm: width (Gaussian sigma, mm) of the gel's elastic skirt around a contact;
    edge_zone_mm: a contact whose indenter axis lies this close to the border (or beyond)
    is labelled 'edge', else 'center'; normal_to_rgb_mlp: path of the FOTS MLP .npz to shade with it instead
    of the analytic model; seed: seed of the internal noise generator.
    """

    px_per_mm: float = field(default=19.58, metadata=check(
        ge=5, le=60, expected="pixels per mm of gel in [5, 60] (about 17-20 for a DIGIT)"))
    background: str | os.PathLike | None = field(default=None, metadata=check(nonempty=True))
    noise_std_bgr: tuple[float, float, float] = field(default=(2.4, 1.3, 2.1), metadata=check(
        ge=0, expected="(B, G, R) noise levels >= 0 (0..255 units)"))
    blur_px: float = field(default=1.2, metadata=check(ge=0))
    skirt_mm: float = field(default=0.9, metadata=check(gt=0))
    edge_zone_mm: float = 2.5
    normal_to_rgb_mlp: str | os.PathLike | None = field(default=None, metadata=check(nonempty=True))
    seed: int = field(default=0, metadata=check(ge=0))
    gel: GelOptions = field(default_factory=GelOptions)
    dome: DomeOptions = field(default_factory=DomeOptions)
    shading: ShadingOptions = field(default_factory=ShadingOptions)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True, slots=True)
class ContactSpec:
    """Where and what touches the gel.

    indenter: catalogue name (see indenters.INDENTERS) or an Indenter; center_px: (row,
    col) of the indenter axis in frame pixels (may lie off the frame for edge contacts);
    rotation_deg: in-plane rotation; stiffness: 'medium' / 'high' / 'very_high' (None: the
    indenter's own); texture_phase: phase (rad) of the print-layer ridges.
    """

    indenter: str | Indenter = field(metadata=check(
        nonempty=True, expected="an indenter name (see indenters.INDENTERS) or an Indenter"))
    center_px: tuple[float, float] = field(default=(160.0, 120.0), metadata=check(
        expected="(row, col) of the indenter axis in frame pixels"))
    rotation_deg: float = 0.0
    stiffness: str | None = None
    texture_phase: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(slots=True)
class SyntheticFrame:
    """One rendered frame: frame 320x240x3 uint8 BGR; height_mm 320x240 float32 gel
    deformation towards the camera (mm); contact_mask 320x240 bool where the body touches the
    gel; force_n the normal force (N); meta: indenter, stiffness, location, pose, depth..."""

    frame: np.ndarray
    height_mm: np.ndarray
    contact_mask: np.ndarray
    force_n: float
    meta: dict = field(default_factory=dict)


def _load_background(path: str | os.PathLike | None = None) -> np.ndarray:
    """A no-contact DIGIT frame (320x240x3 uint8 BGR); the shipped one when path is None."""
    p = Path(path) if path is not None else DEFAULT_BACKGROUND
    img = cv2.imread(str(p), cv2.IMREAD_COLOR)
    if img is None:
        raise FrameError(f"{p}: background image missing or undecodable; expected a 320x240 BGR image")
    return check_frame(img, name=f"background {p}")


class VirtualDigit:
    """Render DIGIT frames of known normal force.

    >>> digit = VirtualDigit(VirtualDigitOptions(seed=1))
    >>> out = digit.render(ContactSpec("circle_large", (160, 120)), force_n=8.0)
    >>> out.frame.shape, out.contact_mask.any()
    ((320, 240, 3), True)
    """

    def __init__(self, options: VirtualDigitOptions = VirtualDigitOptions()) -> None:
        expect(options, VirtualDigitOptions, "VirtualDigit.options")
        self.options = options
        self.background = _load_background(options.background)
        self._bgf = self.background.astype(np.float32)
        self.dome_mm = dome_height_mm((FRAME_ROWS, FRAME_COLS), options.dome)
        ppm = options.px_per_mm
        if options.normal_to_rgb_mlp is not None:
            self.shader: MlpShader | AnalyticShader = MlpShader(options.normal_to_rgb_mlp, ppm)
        else:
            self.shader = AnalyticShader(self.background, ppm, options.shading)
        self._rng = np.random.default_rng(options.seed)
        self._noise_std = np.asarray(options.noise_std_bgr, np.float32)
        self._buf = np.empty((FRAME_ROWS, FRAME_COLS, 3), np.float32)
        self._rows = np.arange(FRAME_ROWS, dtype=np.float32)
        self._cols = np.arange(FRAME_COLS, dtype=np.float32)
        self._skirt_px = options.skirt_mm * ppm
        self._margin = int(math.ceil(3 * self._skirt_px + 3 * options.blur_px)) + 2

    # -- geometry -----------------------------------------------------------------------

    def _geometry(self, ind: Indenter, spec: ContactSpec):
        """Crop box and the gap (mm) between body and domed gel; None if it misses the pad."""
        ppm = self.options.px_per_mm
        r, c = float(spec.center_px[0]), float(spec.center_px[1])
        half = ind.extent_mm * ppm + self._margin
        r0, r1 = max(int(r - half), 0), min(int(math.ceil(r + half)) + 1, FRAME_ROWS)
        c0, c1 = max(int(c - half), 0), min(int(math.ceil(c + half)) + 1, FRAME_COLS)
        if r0 >= r1 or c0 >= c1:
            return None
        th = math.radians(spec.rotation_deg)
        dy = (self._rows[r0:r1, None] - r) / ppm
        dx = (self._cols[None, c0:c1] - c) / ppm
        x = dx * math.cos(th) + dy * math.sin(th)
        y = -dx * math.sin(th) + dy * math.cos(th)
        gap = ind.gap_mm(x, y, ppm, spec.texture_phase) - self.dome_mm[r0:r1, c0:c1]
        finite = np.isfinite(gap)
        if not finite.any():
            return None
        gap -= gap[finite].min()
        return r0, c0, gap.astype(np.float32), finite

    def _location(self, center_px: tuple[float, float]) -> str:
        """'edge' when the indenter axis lies within ``edge_zone_mm`` of the pad border (or off
        it), else 'center'."""
        r, c = float(center_px[0]), float(center_px[1])
        zone = self.options.edge_zone_mm * self.options.px_per_mm
        inside = zone <= r <= FRAME_ROWS - 1 - zone and zone <= c <= FRAME_COLS - 1 - zone
        return "center" if inside else "edge"

    # -- rendering ----------------------------------------------------------------------

    def render(self, contact: ContactSpec | None, force_n: float,
               led_gain: tuple[float, float, float] | np.ndarray | None = None,
               rng: np.random.Generator | None = None) -> SyntheticFrame:
        """Frame of ``contact`` pressed with normal force ``force_n`` (N, >= 0).

        contact None or force 0: a no-contact frame. led_gain: per-channel (B, G, R) LED
        brightness factor (drift); rng: noise generator (default: the digit's own).
        """
        if not (isinstance(force_n, (int, float, np.floating)) and math.isfinite(force_n) and force_n >= 0):
            raise ValueError(f"force_n: {force_n!r}; expected a finite force >= 0 N")
        force_n = float(force_n)
        meta: dict = {"force_n": force_n}
        if contact is None:
            return self._compose(None, force_n, meta, led_gain, rng)
        ind = get_indenter(contact.indenter)
        stiffness = contact.stiffness or ind.stiffness
        meta.update(indenter=ind.name, shape=ind.shape, kind=ind.kind, scale=ind.scale, size_mm=ind.size_mm,
                    stiffness=stiffness, center_px=[round(float(contact.center_px[0]), 2),
                                                    round(float(contact.center_px[1]), 2)],
                    rotation_deg=round(float(contact.rotation_deg), 2))
        geo = self._geometry(ind, contact)
        if geo is None:
            meta.update(location="off_pad", gel_force_n=0.0)
            return self._compose(None, force_n, meta, led_gain, rng)
        r0, c0, gap, finite = geo
        meta["location"] = self._location(contact.center_px)
        f_gel = gel_force(force_n, stiffness, self.options.gel)
        e_star, share = combined_modulus(stiffness, self.options.gel)
        px_area = 1.0 / self.options.px_per_mm ** 2
        if f_gel <= 0:
            d = 0.0
        elif ind.kind == "sphere":
            d = hertz_depth(f_gel, ind.size_mm, e_star)
        elif ind.kind == "flat":
            d = flat_punch_depth(f_gel, float(finite.sum()) * px_area, e_star)
        else:
            d = penalty_depth(f_gel, gap[finite], px_area, e_star, self.options.gel)
        meta["gel_force_n"] = round(f_gel, 4)
        scale = share * onset_visibility(f_gel, self.options.gel)
        return self._deform(gap, r0, c0, d, scale, force_n, meta, led_gain, rng)

    def render_ball_press(self, center_px: tuple[float, float], radius_mm: float, depth_mm: float,
                          led_gain=None, rng: np.random.Generator | None = None) -> SyntheticFrame:
        """A rigid sphere of ``radius_mm`` pressed ``depth_mm`` deep at ``center_px`` (row, col).

        The height map inside the contact is the sphere cap (on the dome); force_n is the
        Hertz force of that depth on this gel. For depth-stage calibration.
        """
        if radius_mm <= 0 or depth_mm < 0 or not math.isfinite(radius_mm + depth_mm):
            raise ValueError(f"radius_mm={radius_mm}, depth_mm={depth_mm}: expected radius > 0 and depth >= 0 (mm)")
        ind = Indenter(f"ball_{radius_mm:g}mm", "sphere", "sphere", float(radius_mm))
        spec = ContactSpec(ind, center_px)
        force = hertz_force(depth_mm, radius_mm, self.options.gel.gel_modulus_mpa)
        meta = {"force_n": force, "indenter": ind.name, "shape": "sphere", "kind": "sphere", "scale": "object",
                "size_mm": float(radius_mm), "stiffness": "very_high",
                "center_px": [float(center_px[0]), float(center_px[1])], "rotation_deg": 0.0}
        geo = self._geometry(ind, spec)
        if geo is None:
            raise ValueError(f"center_px={center_px}: the ball misses the 320x240 pad")
        r0, c0, gap, _ = geo
        meta["location"] = self._location(center_px)
        return self._deform(gap, r0, c0, float(depth_mm), 1.0, force, meta, led_gain, rng)

    def _deform(self, gap, r0, c0, d, scale, force_n, meta, led_gain, rng) -> SyntheticFrame:
        pen = np.maximum(d - gap, 0.0)  # inf gap -> 0
        np.nan_to_num(pen, copy=False, nan=0.0, posinf=0.0)
        gel = (pen * scale).astype(np.float32)
        skirt = cv2.GaussianBlur(gel, (0, 0), self._skirt_px, borderType=cv2.BORDER_REPLICATE)
        height_crop = np.maximum(gel, skirt)
        return self._compose((r0, c0, height_crop, pen > 0), force_n, meta, led_gain, rng)

    def _compose(self, patch, force_n, meta, led_gain, rng) -> SyntheticFrame:
        rng = self._rng if rng is None else rng
        gain = np.ones(3, np.float32) if led_gain is None else np.asarray(led_gain, np.float32).reshape(3)
        buf = self._buf
        np.multiply(self._bgf, gain, out=buf)
        height = np.zeros((FRAME_ROWS, FRAME_COLS), np.float32)
        mask = np.zeros((FRAME_ROWS, FRAME_COLS), bool)
        if patch is not None:
            r0, c0, h, m = patch
            hh, ww = h.shape
            height[r0:r0 + hh, c0:c0 + ww] = h
            mask[r0:r0 + hh, c0:c0 + ww] = m
            delta = self.shader.delta(h, r0, c0)
            if self.options.blur_px > 0:
                delta = cv2.GaussianBlur(delta, (0, 0), self.options.blur_px, borderType=cv2.BORDER_REPLICATE)
            buf[r0:r0 + hh, c0:c0 + ww] += delta * gain
        noise = rng.standard_normal(buf.shape, dtype=np.float32)
        noise *= self._noise_std
        buf += noise
        buf += 0.5
        np.clip(buf, 0.0, 255.0, out=buf)
        frame = buf.astype(np.uint8)
        meta["depth_mm"] = round(float(height.max()), 5)
        meta["contact_area_px"] = int(mask.sum())
        meta["led_gain"] = [round(float(g), 5) for g in gain]
        return SyntheticFrame(frame=frame, height_mm=height, contact_mask=mask, force_n=force_n, meta=meta)
