"""Moved to :mod:`benchmarks.harness.stats`; this path is kept for ``tactile-force bench``'s
import of ``MIN_P99_READINGS`` (edge/cli/bench.py) and warns on import."""

import warnings

from .harness.stats import (  # noqa: F401
    MIN_P99_READINGS,
    NAN_PERCENTILES,
    Percentiles,
    fmt,
    markdown_table,
    mean_std,
    percentiles,
    too_few_for_p99,
)

warnings.warn(f"{__name__} moved to {__name__.rsplit('.', 1)[0]}.harness.stats", DeprecationWarning, stacklevel=2)
