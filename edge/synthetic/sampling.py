"""Random contacts and forces for datasets and grasp sequences (seeded, numpy Generator)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..checks import check_fields
from ..errors import OptionsError
from ..frames import FRAME_COLS, FRAME_ROWS
from ..typed_json import check
from .digit import ContactSpec
from .indenters import STIFFNESS_CLASSES, get_indenter


@dataclass(frozen=True, slots=True)
class ForceDistribution:
    """Normal-force sampling (N): mostly uniform in [low_n, high_n] as the paper's 1-15 N
    dataset; ``below_fraction`` of samples in [0.05, low_n) and ``above_fraction`` in
    (high_n, max_n]."""

    low_n: float = field(default=1.0, metadata=check(gt=0))
    high_n: float = field(default=15.0, metadata=check(gt=0))
    max_n: float = field(default=20.0, metadata=check(gt=0))
    below_fraction: float = field(default=0.0, metadata=check(ge=0, le=1))
    above_fraction: float = field(default=0.0, metadata=check(ge=0, le=1))

    def __post_init__(self) -> None:
        check_fields(self)
        if not self.low_n <= self.high_n <= self.max_n:
            raise OptionsError(f"ForceDistribution: low_n={self.low_n}, high_n={self.high_n}, max_n={self.max_n}; "
                               "expected low_n <= high_n <= max_n (N)")
        if self.below_fraction + self.above_fraction > 1:
            raise OptionsError(f"ForceDistribution: below_fraction={self.below_fraction} + above_fraction="
                               f"{self.above_fraction}; expected a sum in [0, 1]")

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        u = rng.random(n)
        f = rng.uniform(self.low_n, self.high_n, n)
        lo = u < self.below_fraction
        hi = u > 1.0 - self.above_fraction
        f[lo] = rng.uniform(0.05, self.low_n, int(lo.sum()))
        f[hi] = rng.uniform(self.high_n, self.max_n, int(hi.sum()))
        return f


def sample_contact(rng: np.random.Generator, indenter: str, edge_fraction: float = 0.15,
                   stiffness_classes: tuple[str, ...] | None = STIFFNESS_CLASSES) -> ContactSpec:
    """A random pose of ``indenter``: near the pad centre, or (``edge_fraction``) near a border.

    stiffness_classes None: the indenter's own rigidity class.
    """
    ind = get_indenter(indenter)
    if rng.random() < edge_fraction:
        side = int(rng.integers(4))
        t = rng.uniform(0.15, 0.85)
        inset = rng.uniform(-10.0, 35.0)  # px from the border; negative = partly off the pad
        r, c = [(inset, t * FRAME_COLS), (FRAME_ROWS - inset, t * FRAME_COLS),
                (t * FRAME_ROWS, inset), (t * FRAME_ROWS, FRAME_COLS - inset)][side]
    else:
        r = rng.normal(FRAME_ROWS * 0.47, 28.0)
        c = rng.normal(FRAME_COLS * 0.5, 20.0)
    stiff = None if stiffness_classes is None else str(rng.choice(stiffness_classes))
    return ContactSpec(ind.name, (float(r), float(c)), float(rng.uniform(0, 360)), stiff,
                       float(rng.uniform(0, 2 * np.pi)))


def led_gain(rng: np.random.Generator, spread: float = 0.03) -> np.ndarray:
    """Per-channel LED brightness factor around 1 (B, G, R)."""
    common = rng.normal(1.0, spread)
    return (common + rng.normal(0.0, spread / 3, 3)).astype(np.float32)
