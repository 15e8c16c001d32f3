"""Progress bars for long CLI work (calibration, dataset generation, quantization), via tqdm."""

from __future__ import annotations

import os
import sys
from collections.abc import Iterable, Iterator
from typing import TypeVar

from ..interrupts import raise_pending

T = TypeVar("T")


def progress_enabled(enabled: bool = True) -> bool:
    """Whether a bar is drawn: ``enabled`` and stderr is a terminal, or ``TACTILE_FORCE_PROGRESS``
    is set (so logs stay clean in CI and when stderr is redirected)."""
    return bool(enabled and (sys.stderr.isatty() or os.environ.get("TACTILE_FORCE_PROGRESS")))


def progress(items: Iterable[T], total: int | None = None, desc: str = "", enabled: bool = True) -> Iterator[T]:
    """Yield ``items`` while tqdm draws ``desc |####    | i/total [elapsed<eta, rate]`` on stderr.

    Parameters
    ----------
    items : iterable
        What to iterate over; its ``len()`` is the total when it has one.
    total : int, optional
        Number of items, for iterables without ``len()``.
    desc : str
        Label in front of the bar.
    enabled : bool
        False: no bar at all. A bar is also left out when stderr is not a terminal and
        ``TACTILE_FORCE_PROGRESS`` is unset.

    Returns
    -------
    iterator
        The items, unchanged and in order.
    """
    from tqdm import tqdm

    bar = tqdm(items, total=total, desc=desc or None, disable=not progress_enabled(enabled), file=sys.stderr,
               mininterval=0.1, dynamic_ncols=True, leave=True)
    try:
        for item in bar:
            raise_pending()  # a Ctrl-C a library swallowed stops long work at its next step
            yield item
    finally:
        bar.close()
