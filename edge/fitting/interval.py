"""Fitting every reading's error bar: split conformal intervals from (estimate, true force)
pairs the model never trained on (the record is :class:`tactile_force.edge.bundle.interval.ForceInterval`)."""

from __future__ import annotations

import math

import numpy as np

from ..bundle.interval import (
    DEFAULT_COVERAGE,
    DEFAULT_EDGES_N,
    DEFAULT_SCALE_FLOOR_N,
    ForceInterval,
    IntervalBin,
    IntervalError,
)
from ..reading import MAX_VALID_FORCE_N, IntervalState


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
