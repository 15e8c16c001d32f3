"""A dependency-free progress bar for long CLI work (calibration, dataset generation)."""

from __future__ import annotations

import sys
import time
from typing import Iterable, Iterator, TypeVar

T = TypeVar("T")


def progress(items: Iterable[T], total: int | None = None, desc: str = "", enabled: bool = True) -> Iterator[T]:
    """Yield ``items`` while drawing ``desc [####....] i/total  rate  eta`` on stderr.

    Draws at most ~10 times a second; silent when ``enabled`` is False or stderr is not
    a terminal and ``TACTILE_FORCE_PROGRESS`` is unset (logs stay clean in CI).
    """
    import os

    if total is None and hasattr(items, "__len__"):
        total = len(items)  # type: ignore[arg-type]
    show = enabled and (sys.stderr.isatty() or os.environ.get("TACTILE_FORCE_PROGRESS"))
    start = last = time.monotonic()
    i = 0
    for i, item in enumerate(items, 1):
        yield item
        now = time.monotonic()
        if show and (now - last > 0.1 or i == total):
            last = now
            rate = i / max(now - start, 1e-9)
            if total:
                width = 28
                filled = int(width * i / total)
                eta = (total - i) / rate if rate > 0 else 0.0
                bar = "#" * filled + "." * (width - filled)
                sys.stderr.write(f"\r{desc} [{bar}] {i}/{total}  {rate:6.1f}/s  eta {eta:5.1f}s")
            else:
                sys.stderr.write(f"\r{desc} {i}  {rate:6.1f}/s")
            sys.stderr.flush()
    if show:
        sys.stderr.write("\n")
        sys.stderr.flush()
