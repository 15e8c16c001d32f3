"""ForceReading: what the runtime emits for every frame it processes."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

#: The paper's valid force range in newtons: the gel barely deforms below, saturates above.
MIN_VALID_FORCE_N = 1.0
MAX_VALID_FORCE_N = 15.0


class IntervalState(str, enum.Enum):
    """What a reading's ``force_low_n`` / ``force_high_n`` mean.

    ``known``: a central interval holding the true force with the bundle's stated coverage
    (``ForceInterval.coverage``, default 0.90); ``open_above``: the lower bound is known,
    the upper bound is +inf (a ``saturated`` reading: the force may be anything above);
    ``unknown``: both bounds NaN, because there is no estimate (force NaN), the frame was
    read while the gate learnt its background (not judged), or the bundle states no interval
    for it (none recorded, too few labelled frames for the coverage, or recorded for another
    model). Never an invented interval.
    """

    KNOWN = "known"
    OPEN_ABOVE = "open_above"
    UNKNOWN = "unknown"

    def __str__(self) -> str:
        return str(self.value)


class Flags(enum.IntFlag):
    """Quality flags of a reading; combine with ``|``."""

    NONE = 0
    NO_CONTACT = enum.auto()  #: gate closed: force 0 N, the CNN did not run
    BELOW_RANGE = enum.auto()  #: estimate < 1 N, where the gel barely deforms
    SATURATED = enum.auto()  #: estimate >= 15 N, gel saturation seen, or a contact beyond the bundle's data
    LATE = enum.auto()  #: the frame missed its deadline (still reported)
    STALE = enum.auto()  #: a newer frame superseded this one before it was processed
    INVALID_INPUT = enum.auto()  #: wrong shape/dtype, all-dark/white, uniform, noisy or RGB-order frame, NaN
    #: the frame no longer fits the gate's background (another unit or session, moved gel or
    #: camera, sudden LED/exposure step, occlusion): force NaN, the CNN did not run
    BACKGROUND_MISMATCH = enum.auto()
    #: the frame lies outside what the bundle's data covered (manifest data_stats): force kept
    OUT_OF_DISTRIBUTION = enum.auto()

    def names(self) -> list[str]:
        """Lower-case flag names, e.g. ['no_contact'], for CSV/JSON output."""
        return [f.name.lower() for f in Flags if f and f in self and f.name]


@dataclass(slots=True)
class StageLatency:
    """Per-stage wall time of one reading, milliseconds."""

    source_ms: float = 0.0
    gate_ms: float = 0.0
    depth_ms: float = 0.0
    inference_ms: float = 0.0
    total_ms: float = 0.0


@dataclass(slots=True)
class ForceReading:
    """One force estimate.

    force_n: normal force in N, clamped to what the model can honestly say;
    raw_force_n: the model's output before clamping (nan when the CNN did not run);
    truth_n: ground truth when the source knows it;
    force_low_n / force_high_n: the interval (N) that holds the true force with the
    bundle's stated coverage, ``force_low_n <= force_n <= force_high_n``, ``force_low_n >= 0``;
    ``force_high_n`` is +inf when ``interval`` is ``open_above`` (saturated); both NaN when
    ``interval`` is ``unknown`` (see :class:`IntervalState`, :mod:`tactile_force.edge.bundle.interval`).
    """

    sensor: str
    timestamp_ns: int
    frame_index: int
    force_n: float
    flags: Flags = Flags.NONE
    latency: StageLatency = field(default_factory=StageLatency)
    raw_force_n: float = float("nan")
    contact_area_px: int = 0
    truth_n: float | None = None
    detail: str = ""
    force_low_n: float = float("nan")
    force_high_n: float = float("nan")
    interval: IntervalState = IntervalState.UNKNOWN

    def as_dict(self) -> dict:
        """Flat dict for CSV/JSONL writers."""
        return {
            "sensor": self.sensor,
            "timestamp_ns": self.timestamp_ns,
            "frame_index": self.frame_index,
            "force_n": self.force_n,
            "force_low_n": self.force_low_n,
            "force_high_n": self.force_high_n,
            "interval": self.interval.value,
            "raw_force_n": self.raw_force_n,
            "truth_n": self.truth_n,
            "flags": "|".join(self.flags.names()),
            "contact_area_px": self.contact_area_px,
            "source_ms": self.latency.source_ms,
            "gate_ms": self.latency.gate_ms,
            "depth_ms": self.latency.depth_ms,
            "inference_ms": self.latency.inference_ms,
            "total_ms": self.latency.total_ms,
            "detail": self.detail,
        }
