"""The bundle ladder: of several bundles of one model (e.g. fp32, int8, a compact student),
keep the most accurate one whose p99 latency, measured on this host, fits the budget
(a scene's ``[runtime] bundle = [...]``)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import BundleError
from .onnx_model import DEPTH_SHAPE, LOAD_BATCH, RGB_SHAPE, OnnxForceModel


@dataclass
class LadderChoice:
    """The bundle the ladder picked and why; p99_ms per candidate path (calls of the
    runtime's largest batch, 2 by default)."""

    path: Path
    reason: str
    p99_ms: dict[str, float] = field(default_factory=dict)
    score: dict[str, float] = field(default_factory=dict)


def measure_p99_ms(model: OnnxForceModel, runs: int = 30, batch: int = LOAD_BATCH) -> float:
    """p99 wall time (ms) of a predict of ``batch`` frames of zeros (the worst case at run
    time: every sensor in contact; default 2, both fingers of a gripper)."""
    rgb = np.zeros((batch, *RGB_SHAPE), np.uint8)
    depth = np.zeros((batch, *DEPTH_SHAPE), np.uint8) if model.needs_depth else None
    times = []
    for _ in range(runs):
        t0 = time.perf_counter_ns()
        model.predict(rgb, depth)
        times.append((time.perf_counter_ns() - t0) / 1e6)
    return float(np.percentile(times, 99))


def pick_from_ladder(keys: list[str], p99_ms: dict[str, float], score: dict[str, float],
                     budget_ms: float) -> tuple[str, str]:
    """The most accurate key (lowest score, first on ties) whose p99 fits the budget; if none
    fits, the fastest. Returns (key, reason)."""
    fits = [k for k in keys if p99_ms[k] <= budget_ms]
    if fits:
        best = min(fits, key=lambda k: (score[k], keys.index(k)))
        return best, (f"picked {Path(best).name}: most accurate that fits (RE {score[best]:.3g}, "
                      f"p99 {p99_ms[best]:.2f} ms <= budget {budget_ms:.2f} ms)")
    best = min(keys, key=lambda k: p99_ms[k])
    return best, (f"no bundle fits the {budget_ms:.2f} ms budget; picked the fastest, {Path(best).name} "
                  f"(p99 {p99_ms[best]:.2f} ms): readings will be flagged late")


def choose_bundle(paths: list[str | os.PathLike], budget_ms: float, threads: int = 1,
                  runs: int = 30, batch: int = LOAD_BATCH) -> tuple[OnnxForceModel, LadderChoice]:
    """Measure each bundle's p99 (a predict of ``batch`` frames: every sensor of the runtime
    in contact; default 2) and keep the most accurate one (manifest error) whose p99 fits
    ``budget_ms``; if none fits, the fastest. Returns the loaded model and the choice."""
    if not paths:
        raise BundleError("bundle ladder: no bundles given")
    models, p99, score = {}, {}, {}
    for p in paths:
        m = OnnxForceModel(p, threads=threads)
        key = str(p)
        models[key], p99[key], score[key] = m, measure_p99_ms(m, runs, batch), m.bundle.manifest.error_score()
    best, reason = pick_from_ladder(list(models), p99, score, budget_ms)
    return models[best], LadderChoice(Path(best), reason, p99, score)
