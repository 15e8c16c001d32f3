"""Logging helpers shared by the verbs."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator


@contextlib.contextmanager
def quiet_loggers(*names: str, level: int = logging.ERROR) -> Iterator[None]:
    """Only records at ``level`` or above from the loggers ``names`` while the block runs;
    their levels are restored afterwards (a verb called in-process leaves logging as it was).

    Parameters
    ----------
    names : logger names, e.g. ``"tactile_force.edge.bundle.data_stats"``.
    level : the lowest level still emitted meanwhile.
    """
    logs = [logging.getLogger(n) for n in names]
    levels = [log.level for log in logs]
    for log in logs:
        log.setLevel(level)
    try:
        yield
    finally:
        for log, old in zip(logs, levels):
            log.setLevel(old)
