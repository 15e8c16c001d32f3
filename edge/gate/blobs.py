"""The contact gate's blobs: the changed-pixel mask -> contact blobs, filled, their area, gel
saturation and deformation (for edge/gate/contact_gate.py's ``ContactGate``)."""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from .options import GateOptions

__all__ = ["BlobFinder"]


class BlobFinder:
    """Contact blobs of ``mask`` (h x w uint8 0/255, rewritten in place) with ``ad`` (h x w x 3 uint8,
    |frame - model| per channel), both buffers of the gate reused every frame.

    ``finder(changed_px)`` -> (area in working pixels, gel saturation seen, deformation in grey
    levels); ``changed_px`` is the count of 255 pixels in ``mask`` (0: nothing to look at).
    ``stats`` gives the filled mask's (area, deformation) (edge/gate/frame_work.py's
    ``FrameWork.contact_stats``: one compiled pass over ``mask`` and ``ad``)."""

    def __init__(self, options: GateOptions, mask: np.ndarray, ad: np.ndarray,
                 stats: Callable[[], tuple[int, float]]) -> None:
        o = options
        h, w = mask.shape
        self.options = o
        self._mask, self._ad, self._stats = mask, ad, stats
        self._zero = np.zeros(3, np.float64)
        self._sat = np.full(3, float(o.saturation_threshold), np.float64)
        self._strong = np.empty((h, w), np.uint8)
        self._ad_strong = np.empty((h, w, 3), np.uint8)
        self._ad_strong_flat = self._ad_strong.reshape(h, w * 3)  # a view: one value per channel
        # inRange's upper bound on uint8 is the threshold rounded half to even (saturate_cast):
        # the same integer makes cv2.threshold (value > ub) agree with it exactly.
        self._sat_level = min(255, round(float(o.saturation_threshold)))
        self._work_area = h * w
        self._min_blob = o.min_blob_frac * self._work_area
        self._kernel = (cv2.getStructuringElement(cv2.MORPH_RECT, (o.open_px, o.open_px)) if o.open_px > 1
                        else None)

    def __call__(self, changed_px: int) -> tuple[int, bool, float]:
        if not changed_px:
            return 0, False, 0.0
        o = self.options
        mask = self._mask
        if self._kernel is not None:
            cv2.morphologyEx(mask, cv2.MORPH_OPEN, self._kernel, dst=mask)
        # Keep blobs big enough to be contact, filled (a ball's flat top looks like background).
        contours, _ = cv2.findContours(mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        mask.fill(0)
        keep = [c for c in contours if cv2.contourArea(c) >= self._min_blob]
        if not keep:
            return 0, False, 0.0
        if o.convex_hull:
            keep = [cv2.convexHull(c) for c in keep]
        cv2.drawContours(mask, keep, -1, 255, thickness=cv2.FILLED)
        area_small, deformation = self._stats()
        limit = o.saturation_area_frac * self._work_area
        saturation_seen = self._strong_area_reaches(limit) if area_small >= limit else False  # else it cannot be
        return area_small, saturation_seen, deformation

    def _strong_area_reaches(self, limit: float) -> bool:
        """True when the pixels with a channel of ``ad`` above ``saturation_threshold`` cover
        ``limit`` working pixels or more. The changed channel values are counted first (one
        threshold + countNonZero): a pixel holds 1 to 3 of them, so that count alone decides
        unless it lies within [limit, 3 x limit); then the pixels are counted exactly."""
        ub = self._sat_level
        if ub >= 0:
            cv2.threshold(self._ad, ub, 255, cv2.THRESH_BINARY, dst=self._ad_strong)
            values = cv2.countNonZero(self._ad_strong_flat)
            if values < limit:
                return False
            if values >= 3 * limit:
                return True
        cv2.inRange(self._ad, self._zero, self._sat, dst=self._strong)
        return self._work_area - cv2.countNonZero(self._strong) >= limit
