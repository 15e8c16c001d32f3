"""Error bars on every reading: split conformal intervals fitted from labelled data .

A bundle's manifest may hold a :class:`ForceInterval` (``interval``): a table, fitted from
(estimate, true force) pairs the model never trained on, that turns each estimate into an
interval ``[force_low_n, force_high_n]`` holding the true force with a stated coverage
(default 0.90). The runtime applies it to every reading (:meth:`ForceInterval.bounds`, O(1),
no array allocation); :func:`tactile_force.edge.fitting.interval.fit_interval` makes it (numpy only).

Who fits it:

- ``tactile-force export`` (labelled parity data), ``quantize`` (labelled error data),
  ``compress`` (the held-out labelled frames with ``--labels``): on the frames they score on;
- ``tactile-force calibrate-force``: REPLACES it with one fitted on the leave-one-out
  predictions of the user's presses;
- ``python -m benchmarks.interval_fit BUNDLE``: on virtual DIGIT grasps run through the
  runtime (the shipped default bundle's interval).

An interval recorded for another model (``model_sha256``) is not applied: every reading is
then ``unknown``.
"""

from __future__ import annotations

import bisect
import logging
from dataclasses import dataclass, field

from ..errors import TactileForceError
from ..reading import MAX_VALID_FORCE_N, IntervalState

#: The coverage a bundle states when nothing else is asked for.
DEFAULT_COVERAGE = 0.90
#: Upper edges (N) of the estimate bins before merging: [0, 1), [1, 2), [2, 4), [4, 7),
#: [7, 11), [11, 15), [15, inf) (the last holds saturated estimates, clamped at 15 N).
DEFAULT_EDGES_N = (1.0, 2.0, 4.0, 7.0, 11.0, MAX_VALID_FORCE_N)
#: Residuals are divided by max(estimate, this) (N): below it the half-width is absolute (q x 5 N),
#: above it relative (q x the estimate). Errors below ~5 N are mostly absolute (a barely deformed
#: gel, a few tenths of a newton of model noise), above it they grow with the force.
DEFAULT_SCALE_FLOOR_N = 5.0
METHOD = "split-conformal, Mondrian by estimate bin, score |truth - estimate| / max(estimate, floor)"

_log = logging.getLogger(__name__)
_NAN = float("nan")
_INF = float("inf")


class IntervalError(TactileForceError, ValueError):
    """Interval fitting was given unusable input (names the argument and what was expected)."""


@dataclass
class IntervalBin:
    """One estimate bin: estimates in [lo_n, hi_n) (hi_n None: no upper edge) get the
    half-width ``q * max(estimate, scale_floor_n)``; ``q`` None: too few calibration points
    (readings there are ``unknown``). ``n``: calibration points in the bin."""

    lo_n: float
    hi_n: float | None
    n: int
    q: float | None


@dataclass
class ForceInterval:
    """The manifest's ``interval`` record: how a bundle bounds its estimates.

    ``coverage``: the stated probability that the true force lies in a reading's interval;
    ``data``: which labelled frames it was fitted on (never the training or selection data);
    ``n``: (estimate, truth) pairs used; ``bins``: the table; ``no_contact_high_n``: the
    upper bound (N) of a ``no_contact`` reading (gate closed), None when the data had too few
    gate-closed frames (such readings are then ``unknown``); ``model_sha256``: the model the
    estimates came from (the runtime ignores the record on another model).

    Notes
    -----
    Split conformal prediction, Mondrian (class-conditional) by estimate bin. For each
    calibration pair the score is ``s = |y - f| / max(f, floor)`` with ``f`` the estimate as
    the runtime reports it (clamped to [0, 15] N), ``y`` the true force and ``floor``
    ``scale_floor_n`` (5 N: below it the half-width is absolute, above it relative). For a
    saturated reading (``f >= 15`` N, or flagged ``saturated`` by the runtime; its interval
    is open above) only the lower side counts: ``s = max(f - y, 0) / max(f, floor)``; a
    saturated reading whose bin was fitted on two-sided scores gets a lower bound at least as
    low as needed (conservative). In each bin with ``n`` scores the half-width factor is the
    ``ceil((n + 1) * coverage)``-th smallest score; a reading with estimate ``f`` in that bin
    gets ``[max(f - q * max(f, floor), 0), f + q * max(f, floor)]`` (upper +inf when
    saturated). If calibration and use are exchangeable, each bin's interval holds the true
    force with probability >= ``coverage`` (and < ``coverage + 1 / (n + 1)`` for continuous
    scores), whatever the model. A bin with fewer than :func:`min_points` points (9 for
    0.90) is merged with its smaller neighbour until every bin has enough or one remains;
    a single bin still too small gives ``q`` None: the interval is unknown, not invented.
    The lower bound is clipped at 0 N (a normal force is never negative): that removes only
    impossible values, the coverage is unchanged. Frames of one grasp are correlated, so the
    guarantee is over grasps like the ones calibrated on, not per frame; an
    ``out_of_distribution`` frame is by definition not like them (its interval is kept, its
    coverage is not guaranteed). ``no_contact_high_n`` is the same quantile of the true
    forces of gate-closed frames (a one-sided bound, lower bound 0).

    References: Vovk, Gammerman and Shafer, *Algorithmic Learning in a Random World* (2005),
    Mondrian conformal predictors; Lei et al., "Distribution-free predictive inference for
    regression", JASA 2018 (split conformal, locally weighted scores).
    """

    coverage: float = DEFAULT_COVERAGE
    method: str = METHOD
    data: str = ""
    n: int = 0
    n_excluded: int = 0
    scale_floor_n: float = DEFAULT_SCALE_FLOOR_N
    bins: list[IntervalBin] = field(default_factory=list)
    no_contact_n: int = 0
    no_contact_high_n: float | None = None
    model_sha256: str = ""

    def __post_init__(self) -> None:
        try:
            self._cache()
        except (TypeError, ValueError):  # check() reports it (typed_json calls it)
            pass

    def check(self) -> None:
        """Raise ValueError naming the field unless the record is usable."""
        if not 0.0 < self.coverage < 1.0:
            raise ValueError(f"interval.coverage {self.coverage}: expected 0 < coverage < 1")
        if not self.scale_floor_n > 0:
            raise ValueError(f"interval.scale_floor_n {self.scale_floor_n}: expected > 0 N")
        if not self.bins:
            raise ValueError("interval.bins: empty; expected at least one bin")
        if self.bins[0].lo_n != 0.0:
            raise ValueError(f"interval.bins[0].lo_n {self.bins[0].lo_n}: expected 0.0")
        for i, b in enumerate(self.bins):
            last = i == len(self.bins) - 1
            if last != (b.hi_n is None):
                raise ValueError(f"interval.bins[{i}].hi_n: only the last bin has no upper edge (null)")
            if b.hi_n is not None and (not b.hi_n > b.lo_n or (not last and self.bins[i + 1].lo_n != b.hi_n)):
                raise ValueError(f"interval.bins[{i}]: edges must be increasing and contiguous")
            if b.q is not None and not b.q >= 0:
                raise ValueError(f"interval.bins[{i}].q {b.q}: expected >= 0 or null")
            if b.n < 0:
                raise ValueError(f"interval.bins[{i}].n {b.n}: expected >= 0")
        if self.n < 0 or self.n_excluded < 0 or self.no_contact_n < 0:
            raise ValueError(f"interval.n {self.n} / n_excluded {self.n_excluded} / no_contact_n {self.no_contact_n}: "
                             "expected counts >= 0")
        if self.no_contact_high_n is not None and not self.no_contact_high_n >= 0:
            raise ValueError(f"interval.no_contact_high_n {self.no_contact_high_n}: expected >= 0 N or null")
        self._cache()

    def _cache(self) -> None:
        # plain attributes for the hot path (not dataclass fields: never serialised)
        self._edges = [float(b.lo_n) for b in self.bins[1:]]
        self._q = [_NAN if b.q is None else float(b.q) for b in self.bins]
        self._floor = float(self.scale_floor_n)
        nc = self.no_contact_high_n
        self._nc = _NAN if nc is None else float(nc)

    @property
    def known(self) -> bool:
        """True when at least one bin has a finite interval."""
        return any(b.q is not None for b in self.bins)

    def bounds(self, force_n: float, saturated: bool = False) -> tuple[float, float, IntervalState]:
        """``(force_low_n, force_high_n, state)`` for an estimate ``force_n`` (N, as reported).

        O(1) in the number of readings (a bisect over a handful of bin edges), no array
        allocation; NaN estimate or an unknown bin -> ``(nan, nan, UNKNOWN)``; ``saturated``
        -> upper bound +inf, ``OPEN_ABOVE``. Always ``low <= force_n <= high`` and ``low >= 0``
        when known.
        """
        if force_n != force_n:  # NaN
            return _NAN, _NAN, IntervalState.UNKNOWN
        q = self._q[bisect.bisect_right(self._edges, force_n)]
        if q != q:
            return _NAN, _NAN, IntervalState.UNKNOWN
        half = q * (force_n if force_n > self._floor else self._floor)
        low = force_n - half
        if low < 0.0:
            low = 0.0
        if low > force_n:  # force_n < 0 cannot come from the runtime; keep the invariant anyway
            low = force_n
        if saturated:
            return low, _INF, IntervalState.OPEN_ABOVE
        return low, force_n + half, IntervalState.KNOWN

    def no_contact_bounds(self) -> tuple[float, float, IntervalState]:
        """``(0, no_contact_high_n, KNOWN)`` for a gate-closed reading (force 0 N), or
        ``(nan, nan, UNKNOWN)`` when the calibration data had too few gate-closed frames."""
        if self._nc != self._nc:
            return _NAN, _NAN, IntervalState.UNKNOWN
        return 0.0, self._nc, IntervalState.KNOWN


def usable_interval(bundle) -> ForceInterval | None:
    """The bundle's ``interval`` record when it applies to the bundle's model, else None.

    None (every reading ``unknown``) when ``bundle`` is None, the manifest has no interval,
    or the interval was fitted for another model (``model_sha256`` differs from the
    manifest's ``sha256``: the graph changed after the fit; a warning says to refit it).
    """
    manifest = getattr(bundle, "manifest", None)
    iv = getattr(manifest, "interval", None)
    if iv is None:
        return None
    sha = str(getattr(manifest, "sha256", ""))
    if iv.model_sha256 and sha and iv.model_sha256 != sha:
        _log.warning("%s: the manifest's interval was fitted for model sha256 %s..., not this bundle's %s...; "
                     "every reading's interval is 'unknown' (refit: python -m benchmarks.interval_fit BUNDLE, "
                     "or the verb that made the bundle)", getattr(bundle, "path", "bundle"), iv.model_sha256[:12],
                     sha[:12])
        return None
    return iv


__all__ = [
    "DEFAULT_COVERAGE",
    "ForceInterval",
    "IntervalBin",
    "IntervalError",
    "IntervalState",
    "usable_interval",
]
