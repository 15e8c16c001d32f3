"""Error bars on every reading: split conformal intervals fitted from labelled data (issue 21).

A bundle's manifest may hold a :class:`ForceInterval` (``interval``): a table, fitted from
(estimate, true force) pairs the model never trained on, that turns each estimate into an
interval ``[force_low_n, force_high_n]`` holding the true force with a stated coverage
(default 0.90). The runtime applies it to every reading (:meth:`ForceInterval.bounds`, O(1),
no array allocation); :func:`fit_interval` makes it (numpy only).

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
import math
from dataclasses import dataclass, field

import numpy as np

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


def min_points(coverage: float) -> int:
    """The fewest calibration points for which the conformal quantile at ``coverage`` is
    finite: the smallest n with ceil((n + 1) * coverage) <= n (9 for 0.90, 19 for 0.95)."""
    n = 1
    while math.ceil((n + 1) * coverage - 1e-9) > n:
        n += 1
    return n


def conformal_quantile(scores: np.ndarray, coverage: float) -> float | None:
    """The split conformal quantile: the ceil((n+1) * coverage)-th smallest of the n scores,
    None when that rank exceeds n (too few scores for the coverage)."""
    s = np.sort(np.asarray(scores, np.float64).reshape(-1))
    k = math.ceil((s.size + 1) * coverage - 1e-9)
    if k > s.size or k < 1:
        return None
    return float(s[k - 1])


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


def interval_scores(estimate: np.ndarray, truth: np.ndarray, scale_floor_n: float = DEFAULT_SCALE_FLOOR_N,
                    saturated: np.ndarray | None = None) -> np.ndarray:
    """Conformity scores (see :class:`ForceInterval` Notes) of estimates (N, clamped to
    [0, 15] as the runtime reports them) against true forces (N); both shape (n,).
    ``saturated`` (bool, shape (n,)): readings the runtime flagged saturated below 15 N
    (their interval is open above too, so only the lower side counts)."""
    f = np.clip(np.asarray(estimate, np.float64), 0.0, MAX_VALID_FORCE_N)
    y = np.asarray(truth, np.float64)
    scale = np.maximum(f, scale_floor_n)
    open_above = f >= MAX_VALID_FORCE_N
    if saturated is not None:
        open_above = open_above | np.asarray(saturated, bool).reshape(f.shape)
    return np.where(open_above, np.maximum(f - y, 0.0), np.abs(y - f)) / scale


def fit_interval(estimate, truth, coverage: float = DEFAULT_COVERAGE, *, data: str = "", model_sha256: str = "",
                 edges_n: tuple[float, ...] = DEFAULT_EDGES_N, scale_floor_n: float = DEFAULT_SCALE_FLOOR_N,
                 no_contact_truth=None, min_bin_points: int | None = None, saturated=None) -> ForceInterval:
    """Fit a :class:`ForceInterval` from (estimate, true force) pairs the model never trained on.

    Parameters
    ----------
    estimate, truth : array_like, shape (n,)
        The bundle's estimate as the runtime reports it (N; calibrated when the bundle has a
        force calibration; clamped here to [0, 15] N like the runtime) and the true force (N).
        Pairs where either is NaN or infinite are left out (counted in ``n_excluded``).
    coverage : float
        The stated coverage, 0 < coverage < 1 (default 0.90).
    data : str
        Which labelled frames these are (recorded).
    model_sha256 : str
        sha256 of the ONNX model the estimates came from (the runtime checks it).
    edges_n : tuple of float
        Upper edges (N) of the estimate bins before merging, increasing, > 0.
    scale_floor_n : float
        Residuals are divided by max(estimate, scale_floor_n), N.
    no_contact_truth : array_like, optional
        True forces (N) of frames the gate called ``no_contact`` (their upper bound is the
        conformal quantile of these); None: no gate-closed frames (those readings stay unknown).
    min_bin_points : int, optional
        Fewest points a bin keeps before it is merged (default and floor: :func:`min_points`).
    saturated : array_like of bool, shape (n,), optional
        Pairs whose reading the runtime flagged ``saturated`` (open above: one-sided score).

    Returns
    -------
    ForceInterval

    Raises
    ------
    IntervalError
        Shapes differ, coverage outside (0, 1), bad edges or floor.

    Notes
    -----
    See :class:`ForceInterval` (the score, the finite-sample quantile, bin merging).
    """
    if isinstance(coverage, bool) or not isinstance(coverage, (int, float)) or not 0.0 < coverage < 1.0:
        raise IntervalError(f"coverage {coverage!r}: expected a number with 0 < coverage < 1 (e.g. 0.9)")
    if not scale_floor_n > 0:
        raise IntervalError(f"scale_floor_n {scale_floor_n!r}: expected > 0 N")
    edges = [float(e) for e in edges_n]
    if any(e <= 0 for e in edges) or any(b <= a for a, b in zip(edges, edges[1:])):
        raise IntervalError(f"edges_n {edges_n!r}: expected increasing bin edges > 0 N")
    f = np.asarray(estimate, np.float64).reshape(-1)
    y = np.asarray(truth, np.float64).reshape(-1)
    if f.size != y.size:
        raise IntervalError(f"{f.size} estimates for {y.size} true forces; expected one estimate per labelled frame")
    sat = np.zeros(f.size, bool) if saturated is None else np.asarray(saturated, bool).reshape(-1)
    if sat.size != f.size:
        raise IntervalError(f"{sat.size} saturated flags for {f.size} estimates; expected one per estimate")
    ok = np.isfinite(f) & np.isfinite(y)
    f, y, sat = np.clip(f[ok], 0.0, MAX_VALID_FORCE_N), y[ok], sat[ok]
    scores = interval_scores(f, y, scale_floor_n, sat)
    need = max(min_points(coverage), int(min_bin_points or 0))
    # initial bins [lo, hi), then merge the smallest bin with its smaller neighbour until all have enough points
    los = [0.0, *edges]
    members = np.searchsorted(np.asarray(edges), f, side="right")
    groups: list[list[int]] = [[k] for k in range(len(los))]
    counts = [int(np.sum(members == k)) for k in range(len(los))]
    while len(groups) > 1 and min(counts) < need:
        i = int(np.argmin(counts))
        if i == 0:
            j = 1
        elif i == len(groups) - 1:
            j = i - 1
        else:
            j = i - 1 if counts[i - 1] <= counts[i + 1] else i + 1
        a, b = min(i, j), max(i, j)
        groups[a:b + 1] = [groups[a] + groups[b]]
        counts[a:b + 1] = [counts[a] + counts[b]]
    bins = []
    for g_i, g in enumerate(groups):
        sel = np.isin(members, g)
        lo = los[g[0]]
        hi = None if g_i == len(groups) - 1 else los[groups[g_i + 1][0]]
        bins.append(IntervalBin(lo_n=lo, hi_n=hi, n=int(sel.sum()), q=conformal_quantile(scores[sel], coverage)))
    nc_n, nc_high = 0, None
    if no_contact_truth is not None:
        nc = np.asarray(no_contact_truth, np.float64).reshape(-1)
        nc = nc[np.isfinite(nc)]
        nc_n = int(nc.size)
        nc_high = conformal_quantile(np.maximum(nc, 0.0), coverage)
    out = ForceInterval(coverage=float(coverage), data=data, n=int(f.size), n_excluded=int((~ok).sum()),
                        scale_floor_n=float(scale_floor_n), bins=bins, no_contact_n=nc_n, no_contact_high_n=nc_high,
                        model_sha256=model_sha256)
    out.check()
    return out


def interval_coverage(interval: ForceInterval, estimate, truth, saturated=None) -> tuple[int, int, np.ndarray]:
    """Apply ``interval`` to estimates (N, clamped like the runtime) and count how many true
    forces fall inside: returns (inside, known, relative width per pair (nan where unknown or
    open, width / truth)). ``saturated``: optional bool per pair (open above)."""
    f = np.clip(np.asarray(estimate, np.float64).reshape(-1), 0.0, MAX_VALID_FORCE_N)
    y = np.asarray(truth, np.float64).reshape(-1)
    sat = (np.zeros(f.size, bool) if saturated is None else np.asarray(saturated, bool).reshape(-1)) | (
        f >= MAX_VALID_FORCE_N)
    inside = known = 0
    rel = np.full(f.size, np.nan)
    for i in range(f.size):
        lo, hi, st = interval.bounds(float(f[i]), bool(sat[i]))
        if st is IntervalState.UNKNOWN:
            continue
        known += 1
        inside += int(lo <= y[i] <= hi)
        if math.isfinite(hi) and y[i] > 0:
            rel[i] = (hi - lo) / y[i]
    return inside, known, rel


__all__ = [
    "DEFAULT_COVERAGE",
    "ForceInterval",
    "IntervalBin",
    "IntervalError",
    "IntervalState",
    "conformal_quantile",
    "fit_interval",
    "interval_coverage",
    "interval_scores",
    "min_points",
    "usable_interval",
]
