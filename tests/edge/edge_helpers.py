"""Helpers shared by the edge tests (deterministic timing hooks, expected model output)."""

from __future__ import annotations

import numpy as np


def expected_force(frame: np.ndarray, scale: float = 20.0, bias: float = 0.0) -> float:
    return float(scale * frame.astype(np.float64).mean() / 255.0 + bias)


class FakeClock:
    """Deterministic monotonic clock (ns): each call advances by ``step_ns``; ``sleep``
    advances it too. Shared by the runtime and paced sources in timing tests."""

    def __init__(self, step_ns: int) -> None:
        self.t = 1_000_000_000
        self.step_ns = step_ns

    def __call__(self) -> int:
        self.t += self.step_ns
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += int(seconds * 1e9)
