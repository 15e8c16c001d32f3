"""Fitting a per-sensor force calibration: a monotone map from a model's raw estimate to newtons.

Fit (numpy only): isotonic regression (pool-adjacent-violators) of the true force on the raw
estimate, knots at each pooled block's mean raw estimate, straight lines between knots; or
``linear`` (least-squares gain and offset). Outside the data the map continues with the
least-squares slope of all frames, down to 0 N and up past the paper's 15 N (to 20 N), so a
press harder than any calibration press still reads higher, and saturates where the runtime
flags it.

Refusals (:class:`CalibrationRefused`, exit code 2), thresholds in :class:`CalibrationLimits`:

- fewer than 8 labelled frames: leave-one-out needs enough points to mean anything;
- true forces spanning less than 3 N: a gain fitted on a narrow range extrapolates wildly;
- Spearman rank correlation of raw estimate vs truth below 0.8: the model does not order
  these presses by force, so no monotone map can make it right (wrong sensor, wrong model,
  or mislabelled frames);
- a non-positive least-squares slope, non-finite estimates or labels.

Leave-one-out (LOO) error before and after: each frame is predicted by a map fitted on the
other frames, so the "after" figure is what an unseen press of the same kind would get. Both
are the error of the force a reading carries (clamped to [0, 15] N as the runtime clamps it),
by the metric ``run`` reports: the "before" figure is ``run``'s on the same presses. The map
itself is fitted on the unclamped raw estimates (what the runtime calibrates).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..bundle.force_calibration import CalibrationFigures, ForceCalibration
from ..errors import TactileForceError

METHODS = ("isotonic", "linear")


#: The calibrated map is extended linearly up to this force (N); the runtime saturates at 15 N.
EXTRAPOLATE_TO_N = 20.0


class CalibrationRefused(TactileForceError, ValueError):
    """The labelled frames cannot support a trustworthy calibration; nothing was written."""


@dataclass(frozen=True)
class CalibrationLimits:
    """When to refuse: at least ``min_frames`` frames, true forces spanning at least
    ``min_span_n`` N, Spearman rank correlation raw vs truth at least ``min_spearman``."""

    min_frames: int = 8
    min_span_n: float = 3.0
    min_spearman: float = 0.8


def spearman(a: np.ndarray, b: np.ndarray) -> float:
    """Spearman rank correlation (average ranks for ties); nan if either is constant."""
    ra, rb = _ranks(np.asarray(a, np.float64)), _ranks(np.asarray(b, np.float64))
    ra, rb = ra - ra.mean(), rb - rb.mean()
    den = float(np.sqrt((ra * ra).sum() * (rb * rb).sum()))
    return float((ra * rb).sum() / den) if den > 0 else float("nan")


def _ranks(x: np.ndarray) -> np.ndarray:
    order = np.argsort(x, kind="stable")
    ranks = np.empty(x.size, np.float64)
    ranks[order] = np.arange(x.size, dtype=np.float64)
    for v in np.unique(x):  # average the ranks of ties
        sel = x == v
        if sel.sum() > 1:
            ranks[sel] = ranks[sel].mean()
    return ranks


def pav(y: np.ndarray, w: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, list[slice]]:
    """Isotonic (non-decreasing) least-squares fit of ``y`` in the given order.

    Returns (fitted values per sample, block values, block slices). Pool-adjacent-violators:
    O(n) amortised."""
    y = np.asarray(y, np.float64)
    w = np.ones_like(y) if w is None else np.asarray(w, np.float64)
    vals: list[float] = []
    wts: list[float] = []
    starts: list[int] = []
    for i in range(y.size):
        vals.append(float(y[i]))
        wts.append(float(w[i]))
        starts.append(i)
        while len(vals) > 1 and vals[-2] > vals[-1]:
            v2, w2 = vals.pop(), wts.pop()
            starts.pop()
            v1, w1 = vals[-1], wts[-1]
            vals[-1] = (v1 * w1 + v2 * w2) / (w1 + w2)
            wts[-1] = w1 + w2
    ends = starts[1:] + [y.size]
    blocks = [slice(s, e) for s, e in zip(starts, ends)]
    fitted = np.empty_like(y)
    for v, b in zip(vals, blocks):
        fitted[b] = v
    return fitted, np.asarray(vals), blocks


def _ls_slope(raw: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Least-squares (slope, intercept) of truth on raw."""
    dx = raw - raw.mean()
    den = float((dx * dx).sum())
    if den <= 0:  # every estimate equal: no slope
        return float("nan"), float("nan")
    slope = float((dx * (truth - truth.mean())).sum() / den)
    return slope, float(truth.mean() - slope * raw.mean())


def fit_knots(raw: np.ndarray, truth: np.ndarray, method: str = "isotonic") -> tuple[list[float], list[float]]:
    """Knots (raw N, force N) of a monotone piecewise-linear map, with the linear extension to
    0 N and :data:`EXTRAPOLATE_TO_N`. CalibrationRefused if no increasing map fits."""
    if method not in METHODS:
        raise CalibrationRefused(f"--method {method!r}; expected one of {', '.join(METHODS)}")
    raw = np.asarray(raw, np.float64)
    truth = np.asarray(truth, np.float64)
    slope, intercept = _ls_slope(raw, truth)
    if not (slope > 0 and np.isfinite(slope)):
        raise CalibrationRefused(f"the true force does not increase with the model's estimate (least-squares slope "
                                 f"{slope:.3g} N/N); check the labels and that the bundle matches this sensor")
    if method == "linear":
        # the fitted line over the data, cut where it leaves 0 .. EXTRAPOLATE_TO_N N
        lo = max(float(raw.min()), -intercept / slope)
        hi = min(float(raw.max()), (EXTRAPOLATE_TO_N - intercept) / slope)
        if not hi > lo:
            raise CalibrationRefused("the least-squares line gives no force between 0 N and "
                                     f"{EXTRAPOLATE_TO_N:g} N over these estimates; check the labels")
        xs, ys = [lo, hi], [slope * lo + intercept, slope * hi + intercept]
    else:
        order = np.argsort(raw, kind="stable")
        r, t = raw[order], truth[order]
        ur, inv = np.unique(r, return_inverse=True)  # equal estimates: one point, mean label
        w = np.bincount(inv).astype(np.float64)
        ut = np.bincount(inv, weights=t) / w
        _, vals, blocks = pav(ut, w)
        xs = [float(np.average(ur[b], weights=w[b])) for b in blocks]
        ys = [float(v) for v in vals]
        if len(xs) < 2:
            raise CalibrationRefused("the isotonic fit pooled every frame into one level: the model's estimate "
                                     "does not order these presses by force")
    ys = [max(0.0, y) for y in ys]  # a force is >= 0 N (rounding can leave -1e-17); still non-decreasing
    # linear extension with the overall least-squares slope; where the extension is shorter than
    # the float spacing at the end knot (a level a rounding step from 0 or EXTRAPOLATE_TO_N N), the
    # end knot itself takes the limit: knots stay strictly increasing
    if ys[0] > 0:
        x0 = xs[0] - ys[0] / slope
        if x0 < xs[0]:
            xs.insert(0, x0)
            ys.insert(0, 0.0)
        else:
            ys[0] = 0.0
    if ys[-1] < EXTRAPOLATE_TO_N:
        x1 = xs[-1] + (EXTRAPOLATE_TO_N - ys[-1]) / slope
        if x1 > xs[-1]:
            xs.append(x1)
            ys.append(EXTRAPOLATE_TO_N)
        else:
            ys[-1] = EXTRAPOLATE_TO_N
    return xs, ys


def _figures(pred: np.ndarray, truth: np.ndarray) -> CalibrationFigures:
    """RE and MAE of the forces the runtime reports for the estimates ``pred`` (N): clamped to
    [0, 15] N as every reading is (edge/runtime/judging.py, ``Judge.estimate``), by the metric
    ``run`` reports (:func:`~tactile_force.edge.data.metrics.error_stats`), so ``calibrate-force``'s
    "before" figure is ``run``'s error on the same presses and bundle."""
    from ..data.metrics import error_stats
    from ..reading import MAX_VALID_FORCE_N

    st = error_stats(np.clip(np.asarray(pred, np.float64), 0.0, MAX_VALID_FORCE_N), truth)
    return CalibrationFigures(re_mean=st.re_mean, re_std=st.re_std, mae_mean=st.mae_mean, mae_std=st.mae_std,
                              frames=int(st.n))


def leave_one_out(raw: np.ndarray, truth: np.ndarray, method: str = "isotonic") -> np.ndarray:
    """Calibrated estimate (N) of each frame from a map fitted on all the other frames."""
    raw = np.asarray(raw, np.float64)
    truth = np.asarray(truth, np.float64)
    out = np.empty_like(raw)
    for i in range(raw.size):
        keep = np.arange(raw.size) != i
        xs, ys = fit_knots(raw[keep], truth[keep], method)
        out[i] = ForceCalibration(xs, ys).apply(raw[i:i + 1])[0]
    return out


def fit_force_calibration(raw: np.ndarray, truth: np.ndarray, method: str = "isotonic",
                          limits: CalibrationLimits | None = None, data: str = "",
                          model_sha256: str = "") -> ForceCalibration:
    """Fit and check a calibration from raw estimates and true forces (N), both (N,).

    Parameters
    ----------
    raw, truth
        The bundle's uncalibrated estimate and the measured force of each frame, N.
    method
        'isotonic' (default) or 'linear'.
    limits
        Refusal thresholds (:class:`CalibrationLimits`).
    data, model_sha256
        Recorded in the result: where the frames came from, which model was calibrated.

    Returns
    -------
    ForceCalibration with its knots and the leave-one-out error before and after.

    Raises
    ------
    CalibrationRefused
        Too few frames, too narrow a force range, too weak a rank correlation, bad values.
    """
    lim = limits or CalibrationLimits()
    raw = np.asarray(raw, np.float64).reshape(-1)
    truth = np.asarray(truth, np.float64).reshape(-1)
    if raw.size != truth.size:
        raise CalibrationRefused(f"{raw.size} estimates for {truth.size} labels")
    if not np.all(np.isfinite(truth)):
        raise CalibrationRefused("a true force is NaN or infinite; fix the force files")
    if not np.all(np.isfinite(raw)):
        raise CalibrationRefused("the model gave a non-finite estimate on a calibration frame; check the frames "
                                 "(320x240 BGR DIGIT portrait) and the bundle")
    if raw.size < lim.min_frames:
        raise CalibrationRefused(f"only {raw.size} labelled frame(s); at least {lim.min_frames} are needed "
                                 "(10-30 presses covering the force range you will use)")
    span = float(truth.max() - truth.min())
    if span < lim.min_span_n:
        raise CalibrationRefused(f"the true forces span only {span:.2f} N ({truth.min():.2f} to {truth.max():.2f} N); "
                                 f"at least {lim.min_span_n:g} N is needed: press from light to firm")
    rho = spearman(raw, truth)
    if not (rho >= lim.min_spearman):
        raise CalibrationRefused(f"the model's estimate is not monotone enough in the true force (Spearman rank "
                                 f"correlation {rho:.2f} < {lim.min_spearman:g}); a monotone calibration cannot fix "
                                 "that: check the labels, that frames and forces are paired, and the bundle")
    xs, ys = fit_knots(raw, truth, method)
    after = leave_one_out(raw, truth, method)
    cal = ForceCalibration(raw_n=xs, force_n=ys, method=method, frames=int(raw.size), data=data,
                           force_range_n=[float(truth.min()), float(truth.max())], spearman=rho,
                           model_sha256=model_sha256, loo_before=_figures(raw, truth),
                           loo_after=_figures(after, truth))
    cal.check()
    return cal
