"""The paper's error metrics (Section "Metric Evaluation").

RE  = |f_pred - f_gt| / f_gt   per sample, reported as mean +- std (population std, ddof=0)
MAE = |f_pred - f_gt|          per sample, reported as mean +- std (ddof=0)

Samples whose ground truth is <= 0 N have no relative error; they are excluded from RE
(and counted in ``n_excluded_re``) but kept in MAE. Force bins are 1 N wide and
left-closed: bin k holds k <= f_gt < k + 1.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from ..reading import Flags, ForceReading


@dataclass(slots=True)
class ErrorStats:
    """RE (dimensionless) and MAE (N) as mean +- std over ``n`` samples."""

    n: int
    re_mean: float
    re_std: float
    mae_mean: float
    mae_std: float
    n_excluded_re: int = 0

    def as_dict(self) -> dict:
        return asdict(self)

    def __str__(self) -> str:
        return (f"RE {self.re_mean:.3f} +- {self.re_std:.3f}, MAE {self.mae_mean:.3f} +- "
                f"{self.mae_std:.3f} N (n={self.n})")


@dataclass(slots=True)
class ErrorBreakdown:
    """Overall stats plus per-1-N-bin and per-group breakdowns."""

    overall: ErrorStats
    per_bin: dict[str, ErrorStats] = field(default_factory=dict)
    per_group: dict[str, dict[str, ErrorStats]] = field(default_factory=dict)

    def as_dict(self) -> dict:
        return {
            "overall": self.overall.as_dict(),
            "per_bin": {k: v.as_dict() for k, v in self.per_bin.items()},
            "per_group": {g: {k: v.as_dict() for k, v in d.items()} for g, d in self.per_group.items()},
        }


def _as_1d(x: Sequence[float] | np.ndarray, name: str) -> np.ndarray:
    a = np.asarray(x, dtype=np.float64).reshape(-1)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains NaN or inf; metrics need finite forces in N")
    return a


def relative_error(pred: Sequence[float] | np.ndarray, truth: Sequence[float] | np.ndarray) -> np.ndarray:
    """Per-sample RE = |pred - truth| / truth. Samples with truth <= 0 give NaN."""
    p, t = _as_1d(pred, "pred"), _as_1d(truth, "truth")
    if p.shape != t.shape:
        raise ValueError(f"pred has {p.size} samples but truth has {t.size}")
    out = np.full_like(t, np.nan)
    ok = t > 0
    out[ok] = np.abs(p[ok] - t[ok]) / t[ok]
    return out


def error_stats(pred: Sequence[float] | np.ndarray, truth: Sequence[float] | np.ndarray) -> ErrorStats:
    """RE and MAE, mean +- std (ddof=0), over matched samples of predicted and true force (N)."""
    p, t = _as_1d(pred, "pred"), _as_1d(truth, "truth")
    if p.shape != t.shape:
        raise ValueError(f"pred has {p.size} samples but truth has {t.size}")
    if p.size == 0:
        raise ValueError("error_stats: no samples")
    ae = np.abs(p - t)
    re = relative_error(p, t)
    re_ok = re[np.isfinite(re)]
    return ErrorStats(
        n=int(p.size),
        re_mean=float(re_ok.mean()) if re_ok.size else float("nan"),
        re_std=float(re_ok.std()) if re_ok.size else float("nan"),
        mae_mean=float(ae.mean()),
        mae_std=float(ae.std()),
        n_excluded_re=int(p.size - re_ok.size),
    )


def force_bin_label(f_gt: float) -> str:
    """Label of the 1 N bin holding ``f_gt``: '3-4' for 3 <= f < 4."""
    k = int(np.floor(f_gt))
    return f"{k}-{k + 1}"


def error_report(
    pred: Sequence[float] | np.ndarray,
    truth: Sequence[float] | np.ndarray,
    groups: dict[str, Iterable[str]] | None = None,
) -> ErrorBreakdown:
    """Overall, per-1-N-bin and per-group error stats.

    groups: optional mapping group name (e.g. 'shape', 'stiffness', 'location') to one
    label per sample.
    """
    p, t = _as_1d(pred, "pred"), _as_1d(truth, "truth")
    report = ErrorBreakdown(overall=error_stats(p, t))
    bins = np.floor(t).astype(int)
    for k in sorted(set(bins.tolist())):
        sel = bins == k
        report.per_bin[f"{k}-{k + 1}"] = error_stats(p[sel], t[sel])
    for gname, labels in (groups or {}).items():
        lab = np.asarray(list(labels))
        if lab.size != p.size:
            raise ValueError(f"group '{gname}' has {lab.size} labels for {p.size} samples")
        report.per_group[gname] = {str(v): error_stats(p[lab == v], t[lab == v]) for v in sorted(set(lab.tolist()))}
    return report


def cnn_readings(readings: list[ForceReading]) -> list[ForceReading]:
    """Readings where the CNN gave a force and the frame has a truth > 0 N (what RE/MAE are over)."""
    skip = Flags.NO_CONTACT | Flags.INVALID_INPUT | Flags.STALE
    return [r for r in readings if not (r.flags & skip) and math.isfinite(r.force_n)
            and r.truth_n is not None and r.truth_n > 0]


def readings_error(readings: list[ForceReading]) -> tuple[ErrorBreakdown | None, int, int]:
    """The error of a replay with truth, as ``run`` reports it: (ErrorBreakdown over
    :func:`cnn_readings` or None when there is none, frames with truth, frames with truth
    >= 1 N that got no CNN reading). ``tactile-force bench --data`` reports the same figures."""
    with_truth = [r for r in readings if r.truth_n is not None and Flags.STALE not in r.flags]
    cnn = cnn_readings(readings)
    in_cnn = {id(r) for r in cnn}
    missed = sum(1 for r in with_truth if r.truth_n is not None and r.truth_n >= 1.0 and id(r) not in in_cnn)
    rep = error_report([r.force_n for r in cnn], [float(r.truth_n or 0.0) for r in cnn]) if cnn else None
    return rep, len(with_truth), missed
