"""The host a figure was made on, in one line: ``CPU: <model>, <n> logical cores``.

Standard library only, so ``tactile-force demo`` and ``bench`` print it without loading
anything else; :mod:`tactile_force.benchmarks.harness.machine` reads the CPU model here too."""

from __future__ import annotations

import os
import platform


def cpu_model() -> str:
    """The CPU model (``model name`` of /proc/cpuinfo), else what :mod:`platform` knows."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown CPU"


def cpu_line(model: str | None = None, cores: int | None = None) -> str:
    """``CPU: <model>, <cores> logical cores``; this host's model and core count unless given."""
    n = (os.cpu_count() or 1) if cores is None else cores
    return f"CPU: {cpu_model() if model is None else model}, {n} logical core{'s' if n != 1 else ''}"


__all__ = ["cpu_line", "cpu_model"]
