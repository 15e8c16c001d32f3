"""Statistics of the frames a bundle's model was trained or calibrated on (manifest ``data_stats``).

Initial record; the out-of-distribution check that uses it lives with the gate.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class DataStats:
    """Cheap statistics of the frames a bundle saw (low resolution, BGR order)."""

    frames: int = 0
    channel_mean_lo: list[float] = field(default_factory=list)
    channel_mean_hi: list[float] = field(default_factory=list)
    channel_std_lo: list[float] = field(default_factory=list)
    channel_std_hi: list[float] = field(default_factory=list)
    contact_area_max_frac: float | None = None
    deformation_max: float | None = None
    source: str = ""
