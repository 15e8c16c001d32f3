"""Statistics of the frames a bundle's model was trained or calibrated on (manifest ``data_stats``),
and the cheap per-frame check the runtime runs against them.

A bundle records, at low resolution, the range of colours its data showed in every region of
the frame, and the largest contact (area, deformation) the contact gate saw in it. At run time
:class:`DataStatsCheck` compares the gate's 20x15 thumbnail of each frame with those ranges
(``out_of_distribution``, force kept) and the gate's contact with the largest one seen
(``saturated``: the gel shows more than the data covered). numpy only: this module is
imported with every manifest; measuring the statistics from frames is
:mod:`tactile_force.edge.fitting.data_stats`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

_log = logging.getLogger(__name__)


@dataclass
class DataStats:
    """Cheap statistics of the frames a bundle saw (BGR, grey levels 0..255).

    frames: frames the statistics come from; contact_frames: of which the gate saw contact.
    thumb_rows / thumb_cols: the thumbnail grid (one cell = 16x16 frame pixels; 20x15 for a
        320x240 DIGIT frame).
    cell_lo / cell_hi: per cell and channel (row-major, then B, G, R; rows x cols x 3 values)
        the 0.5th / 99.5th percentile of the cell's mean colour over the frames.
    channel_mean / channel_std: per channel (B, G, R) mean and spread of the frames' mean colour.
    contact_area_frac_max: the largest contact area the gate saw, as a fraction of the frame
        (None: no contact in the data).
    deformation_max: the largest deformation the gate saw: mean colour change inside the
        contact mask (grey levels, max over channels; None: no contact in the data).
    contact_measured: False when no no-contact background was given: the colour ranges (the
        out-of-distribution check) are recorded, the contact sizes are not (contact-size check off).
    background_thumb: the no-contact background's colours on the same grid (INTER_AREA of the
        first background frame; B, G, R per cell; empty without a background): the runtime
        checks a background given to it for a press against it (edge/gate/given_background.py).
    margin: grey levels added on both sides of every cell's range by the check.
    max_outside_frac: share of thumbnail values outside their ranges above which a frame is
        out of distribution.
    source: what the frames were (e.g. "synthetic train split (S1), 600 frames").
    """

    frames: int = 0
    contact_frames: int = 0
    thumb_rows: int = 20
    thumb_cols: int = 15
    cell_lo: list[float] = field(default_factory=list)
    cell_hi: list[float] = field(default_factory=list)
    channel_mean: list[float] = field(default_factory=list)
    channel_std: list[float] = field(default_factory=list)
    contact_area_frac_max: float | None = None
    deformation_max: float | None = None
    contact_measured: bool = True
    background_thumb: list[float] = field(default_factory=list)
    margin: float = 12.0
    max_outside_frac: float = 0.10
    source: str = ""

    def check(self) -> None:
        """Raise ValueError naming the first field that does not fit the others."""
        n = self.thumb_rows * self.thumb_cols * 3
        if self.thumb_rows < 1 or self.thumb_cols < 1:
            raise ValueError(f"thumb_rows={self.thumb_rows}, thumb_cols={self.thumb_cols}: expected >= 1")
        for name in ("cell_lo", "cell_hi"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"{name}: {len(getattr(self, name))} values; "
                                 f"expected thumb_rows x thumb_cols x 3 = {n}")
        if self.background_thumb and len(self.background_thumb) != n:
            raise ValueError(f"background_thumb: {len(self.background_thumb)} values; expected {n} (or none)")
        for name in ("channel_mean", "channel_std"):
            if len(getattr(self, name)) not in (0, 3):
                raise ValueError(f"{name}: {len(getattr(self, name))} values; expected 3 (B, G, R)")
        if self.margin < 0 or not 0 < self.max_outside_frac < 1:
            raise ValueError(f"margin={self.margin}, max_outside_frac={self.max_outside_frac}: expected margin >= 0 "
                             "and 0 < max_outside_frac < 1")
        # every range ordered: swapped colour ranges would make every frame out of distribution
        bad = [i for i, (lo, hi) in enumerate(zip(self.cell_lo, self.cell_hi)) if not lo <= hi]
        if bad:
            i = bad[0]
            raise ValueError(f"cell_lo[{i}] {self.cell_lo[i]:g} > cell_hi[{i}] {self.cell_hi[i]:g} ({len(bad)} of {n} "
                             "cells): expected every cell's colour range low <= high (grey levels)")
        for name in ("cell_lo", "cell_hi", "background_thumb", "channel_mean"):
            values = getattr(self, name)
            if values and not all(0 <= v <= 255 for v in values):
                raise ValueError(f"{name}: values outside 0..255; expected grey levels")
        if any(not v >= 0 for v in self.channel_std):
            raise ValueError(f"channel_std {self.channel_std}: expected spreads >= 0")
        if not 0 <= self.contact_frames <= self.frames:
            raise ValueError(f"contact_frames {self.contact_frames} of frames {self.frames}: expected "
                             "0 <= contact_frames <= frames")
        if self.contact_area_frac_max is not None and not 0 <= self.contact_area_frac_max <= 1:
            raise ValueError(f"contact_area_frac_max {self.contact_area_frac_max}: expected a fraction in [0, 1]")
        if self.deformation_max is not None and not self.deformation_max >= 0:
            raise ValueError(f"deformation_max {self.deformation_max}: expected >= 0 grey levels")


class DataStatsCheck:
    """The per-frame check against a bundle's :class:`DataStats` (a few microseconds).

    ``stats`` None: every check passes and one warning says the check is skipped.
    """

    def __init__(self, stats: DataStats | None, bundle_name: str = "bundle") -> None:
        self.stats = stats
        self._warned = False
        self._name = bundle_name
        if stats is None:
            _log.warning("%s: manifest has no data_stats; the out-of-distribution check is skipped", bundle_name)
            self._warned = True
            return
        stats.check()
        shape = (stats.thumb_rows, stats.thumb_cols, 3)
        m = stats.margin
        self._lo = np.clip(np.floor(np.asarray(stats.cell_lo, np.float64) - m), 0, 255).astype(np.uint8).reshape(shape)
        self._hi = np.clip(np.ceil(np.asarray(stats.cell_hi, np.float64) + m), 0, 255).astype(np.uint8).reshape(shape)
        self._limit = int(stats.max_outside_frac * self._lo.size)
        # one value per column (rows x cols*3, single channel): inRange judges every channel
        # value on its own, into a buffer made once
        flat = (stats.thumb_rows, stats.thumb_cols * 3)
        self._lo_flat, self._hi_flat = self._lo.reshape(flat), self._hi.reshape(flat)
        self._inside = np.empty(flat, np.uint8)
        self._area_max = stats.contact_area_frac_max
        self._deform_max = stats.deformation_max

    @property
    def active(self) -> bool:
        return self.stats is not None

    def out_of_distribution(self, thumb: np.ndarray | None) -> str:
        """Why the frame (its gate thumbnail, rows x cols x 3 uint8) lies outside the data, or ""."""
        if self.stats is None or thumb is None:
            return ""
        if thumb.shape != self._lo.shape:
            if not self._warned:
                _log.warning("%s: frame thumbnail %s does not match the data_stats grid %s; out-of-distribution "
                             "check skipped", self._name, thumb.shape, self._lo.shape)
                self._warned = True
            return ""
        import cv2  # here, so that importing tactile_force.edge stays light

        flat = np.ascontiguousarray(thumb).reshape(self._inside.shape)
        cv2.inRange(flat, self._lo_flat, self._hi_flat, dst=self._inside)  # lo <= value <= hi
        outside = thumb.size - cv2.countNonZero(self._inside)
        if outside > self._limit:
            return (f"{100.0 * outside / thumb.size:.0f} % of the frame's low-resolution colours lie outside what "
                    f"the bundle's data covered (another sensor, lighting or gel than the model saw)")
        return ""

    def beyond_coverage(self, area_frac: float, deformation: float) -> str:
        """Why the contact is larger or deeper than any in the bundle's data, or ""."""
        if self._area_max is not None and area_frac > self._area_max:
            return (f"contact area {100 * area_frac:.0f} % of the frame exceeds the largest in the bundle's data "
                    f"({100 * self._area_max:.0f} %): the estimate is a lower bound")
        if self._deform_max is not None and deformation > self._deform_max:
            return (f"deformation {deformation:.0f} grey levels exceeds the largest in the bundle's data "
                    f"({self._deform_max:.0f}): the estimate is a lower bound")
        return ""


