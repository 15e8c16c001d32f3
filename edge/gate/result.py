"""One contact gate decision (:class:`GateResult`, made by edge/gate/contact_gate.py's ``ContactGate``)."""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["GateResult"]


class GateResult:
    """One gate decision.

    contact: gate open (after hysteresis). area_px: masked area in full-resolution pixels;
    area_frac: the same as a fraction of the frame. saturation_seen: a large strongly changed
    area. background_ready: False while the background is still being learnt (then contact
    is False). mismatch: why the frame does not fit the background ("" = it fits; then
    contact is False). invalid: why the frame cannot be judged at all (colour order, uniform,
    noise; "" = fine). deformation: mean compensated colour difference inside the mask (grey
    levels; 0 without contact). thumb: the frame's 20x15x3 uint8 thumbnail (a buffer the
    gate reuses). gain / offset: the fitted per-channel (B, G, R) photometric change.

    mask (HxW uint8 0/255 at the frame's full resolution), centroid ((x, y) pixels or None)
    and bbox ((x, y, w, h) pixels or None) are computed on first access from the gate's
    working mask, so the hot path of an RGBmod scene, which reads neither, skips the
    upscale and the moments. The mask is a buffer the gate reuses: read or copy it before
    the next ``update``.
    """

    __slots__ = ("contact", "area_px", "area_frac", "saturation_seen", "background_ready", "mismatch", "invalid",
                 "deformation", "thumb", "gain", "offset", "reduced", "_small", "_k", "_exact", "_full", "_mask_ready",
                 "_geometry")

    def __init__(self, contact: bool, area_px: int, saturation_seen: bool, small: np.ndarray, full: np.ndarray,
                 k: int, exact: bool, background_ready: bool = True) -> None:
        self.contact = contact
        self.area_px = area_px
        self.area_frac = area_px / float(full.shape[0] * full.shape[1])
        self.saturation_seen = saturation_seen
        self.background_ready = background_ready
        self.mismatch = ""
        self.invalid = ""
        self.deformation = 0.0
        self.thumb: np.ndarray | None = None
        #: the frame reduced by the gate's :attr:`ContactGate.reduction` (H/k x W/k x 3 uint8, a
        #: buffer the gate reuses: the image the model reads when its reduction is the same)
        self.reduced: np.ndarray | None = None
        self.gain: tuple[float, float, float] = (1.0, 1.0, 1.0)
        self.offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._small, self._full, self._k, self._exact = small, full, k, exact
        self._mask_ready = small is full
        self._geometry: tuple | None = None

    @property
    def mask_computed(self) -> bool:
        """True once the full-resolution mask exists (it is made on first read of ``mask``)."""
        return self._mask_ready

    @property
    def reduced_mask(self) -> np.ndarray:
        """The gate's working mask (H/k x W/k uint8 0/255, a buffer it reuses), the mask of
        :attr:`reduced`: what a depth stage at the network resolution reads (``mask`` is this
        one upscaled by nearest neighbour)."""
        return self._small

    @property
    def mask(self) -> np.ndarray:
        if not self._mask_ready:
            cv2.resize(self._small, (self._full.shape[1], self._full.shape[0]), dst=self._full,
                       interpolation=cv2.INTER_NEAREST)
            self._mask_ready = True
        return self._full

    def _measure(self) -> tuple:
        if self._geometry is None:
            if not self.area_px:
                self._geometry = (None, None)
            else:
                # From the small mask when the factor divides the frame (the nearest-neighbour
                # upscale maps every small pixel to a k x k block: exact), else the full mask.
                src, k = (self._small, self._k) if self._exact else (self.mask, 1)
                m = cv2.moments(src, binaryImage=True)
                off = (k - 1) / 2.0
                x, y, w, h = cv2.boundingRect(src)
                self._geometry = ((k * m["m10"] / m["m00"] + off, k * m["m01"] / m["m00"] + off),
                                  (int(x * k), int(y * k), int(w * k), int(h * k)))
        return self._geometry

    @property
    def centroid(self) -> tuple[float, float] | None:
        return self._measure()[0]

    @property
    def bbox(self) -> tuple[int, int, int, int] | None:
        return self._measure()[1]

    def __repr__(self) -> str:
        return (f"GateResult(contact={self.contact}, area_px={self.area_px}, saturation_seen={self.saturation_seen}, "
                f"background_ready={self.background_ready}, mismatch={self.mismatch!r}, invalid={self.invalid!r})")
