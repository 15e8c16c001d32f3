"""Percentiles and Markdown tables: the small, tested core of every benchmark table."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Percentiles:
    """p50 / p90 / p99 / mean of a latency sample in ms, and how many samples."""

    p50: float
    p90: float
    p99: float
    mean: float
    n: int

    def as_dict(self) -> dict:
        return {"p50": self.p50, "p90": self.p90, "p99": self.p99, "mean": self.mean, "n": self.n}


NAN_PERCENTILES = Percentiles(math.nan, math.nan, math.nan, math.nan, 0)

#: readings a p99 verdict needs at least: the p99 is the value 1 % of readings exceed, so with
#: fewer than 100 not one reading lies above it and it is only the largest reading seen.
MIN_P99_READINGS = 100


def too_few_for_p99(n: int) -> str | None:
    """Why ``n`` readings give no p99 verdict (a sentence), or None when they are enough."""
    if n >= MIN_P99_READINGS:
        return None
    return (f"too few readings for a p99 verdict: {n} < {MIN_P99_READINGS} (the p99 is the value 1 % of readings "
            f"exceed; with fewer than {MIN_P99_READINGS} it is only the largest reading)")


def percentiles(samples_ms: Sequence[float] | np.ndarray) -> Percentiles:
    """Percentiles (linear interpolation, numpy's default) of finite samples; NaNs if none."""
    x = np.asarray(samples_ms, dtype=np.float64).reshape(-1)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return NAN_PERCENTILES
    p50, p90, p99 = np.percentile(x, [50, 90, 99])
    return Percentiles(float(p50), float(p90), float(p99), float(x.mean()), int(x.size))


def fmt(v: object, digits: int = 3) -> str:
    """Number for a table cell: '-' for None/NaN, fixed decimals for floats, other values as text."""
    if v is None:
        return "-"
    if not isinstance(v, (int, float, np.number)):
        return str(v)
    if isinstance(v, (int, np.integer)) and not isinstance(v, bool):
        return str(int(v))
    if not math.isfinite(float(v)):
        return "-"
    return f"{float(v):.{digits}f}"


def markdown_table(headers: Sequence[str], rows: Sequence[Sequence[object]], digits: int = 3) -> str:
    """A GitHub Markdown table; cells formatted with :func:`fmt`. Rows must match the header width."""
    for i, r in enumerate(rows):
        if len(r) != len(headers):
            raise ValueError(f"markdown_table: row {i} has {len(r)} cells; header has {len(headers)}")
    lines = ["| " + " | ".join(headers) + " |", "|" + "|".join("---" for _ in headers) + "|"]
    lines += ["| " + " | ".join(fmt(c, digits) for c in r) + " |" for r in rows]
    return "\n".join(lines)


def mean_std(x: Sequence[float] | np.ndarray) -> str:
    """'m +- s' of finite values, '-' if none."""
    a = np.asarray(x, dtype=np.float64)
    a = a[np.isfinite(a)]
    if a.size == 0:
        return "-"
    return f"{a.mean():.3f} +- {a.std():.3f}"
