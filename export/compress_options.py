"""What ``compress`` is asked for: the ladder of students (:class:`Rung`, ``--ladder`` parsed by
:func:`parse_ladder`), the options, the result and the error of bad input (export/compress.py
runs it)."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from tactile_force.edge.bundle.store import Bundle
from tactile_force.edge.errors import TactileForceError

from .training import Augment
from .zoo import RESNET18_BLOCKS, ModelSpec, blocks_tag, check_blocks


class CompressError(TactileForceError, ValueError):
    """Bad input to compress (frames, teacher, options); nothing was written."""


@dataclass(frozen=True)
class Rung:
    """One student of the ladder: RGBmod at width multiplier ``width``, input scale 1/``k``
    and ``blocks`` residual blocks per stage (ResNet-18's (2, 2, 2, 2) unless fewer)."""

    width: float
    k: int
    blocks: tuple[int, int, int, int] = RESNET18_BLOCKS

    @property
    def name(self) -> str:
        return f"rgbmod-w{self.width:g}-s{self.k}{blocks_tag(self.blocks)}"

    @property
    def spec(self) -> ModelSpec:
        return ModelSpec("rgbmod", self.width, 1.0 / self.k, self.blocks)

    @property
    def text(self) -> str:
        """The rung as ``--ladder`` writes it: '0.25x4', '0.25x4b1111'."""
        return f"{self.width:g}x{self.k}{blocks_tag(self.blocks).replace('-b', 'b')}"


#: The default ladder, cheapest first (0.005 to 0.06 GMAC a frame): narrower, smaller-input
#: and fewer-blocks students (one block per stage: about half the layers of ResNet-18's two).
DEFAULT_LADDER: tuple[Rung, ...] = (Rung(0.125, 8), Rung(0.25, 4, (1, 1, 1, 1)), Rung(0.25, 4),
                                    Rung(0.5, 4, (1, 1, 1, 1)), Rung(0.5, 4), Rung(0.25, 2))


def parse_ladder(text: str) -> tuple[Rung, ...]:
    """'0.25x4,0.5x4b1111' -> rungs (width x k, optionally b + four blocks-per-stage digits)."""
    import re

    rungs = []
    for part in (p.strip() for p in text.split(",")):
        m = re.fullmatch(r"([0-9]*\.?[0-9]+)x([0-9]+)(?:b([0-9]{4}))?", part.lower())
        try:
            if m is None:
                raise ValueError(part)
            blocks = tuple(int(c) for c in m.group(3)) if m.group(3) else RESNET18_BLOCKS
            rungs.append(Rung(float(m.group(1)), int(m.group(2)), check_blocks(blocks)))
        except (ValueError, TactileForceError):
            raise CompressError(f"--ladder {part!r}: expected WIDTHxK or WIDTHxKbNNNN, e.g. 0.25x4 (width 0.25, "
                                "input 1/4) or 0.25x4b1111 (the same with one residual block per stage)") from None
    if not rungs:
        raise CompressError("--ladder: no students given")
    return tuple(rungs)


@dataclass
class CompressOptions:
    """What to compress and how.

    teacher: checkpoint (.pth / .pth.tar) or fp32 bundle folder (RGBmod). frames: unlabelled
    inputs. labels: an authors'-layout folder of labelled frames. out: output folder.
    budget_ms: p99 budget per batch-2 inference on this host. epochs, lr, batch: training.
    max_frames: unlabelled frames used at most (evenly subsampled). val_share: held-out
    share of the unlabelled frames. latency_runs: timed batch-2 calls per block;
    latency_blocks: blocks per student, timed round-robin over all students once they are
    trained; a student's p99 is the median of its block p99s (one noisy block cannot flip
    the choice). max_vs_teacher_re: the largest RE against the teacher (held-out unlabelled
    frames) a student may have to be written as the result (default 0.25; the distillation
    study's students are at 0.01-0.07): a worse student is not a compressed teacher.
    on_student: called with each student's record when it is trained (tests use it).
    background: a no-contact frame (or its image path) of the sensor the frames come from:
    with it the bundle's ``data_stats`` also record contact sizes (the contact-size check);
    without it only the frames' colours (the out-of-distribution check), with a warning.
    """

    teacher: str | os.PathLike
    frames: list[str | os.PathLike]
    out: str | os.PathLike
    labels: str | os.PathLike | None = None
    budget_ms: float = 1.0
    seed: int = 0
    ladder: tuple[Rung, ...] = DEFAULT_LADDER
    epochs: int = 30
    lr: float = 1e-3
    batch: int = 64
    augment: Augment | None = field(default_factory=Augment)
    max_frames: int = 6000
    val_share: float = 0.15
    threads: int | None = None
    latency_runs: int = 200
    latency_blocks: int = 5
    max_vs_teacher_re: float = 0.25
    calibration_frames: int = 200
    show_progress: bool = False
    on_student: Callable[[dict], None] | None = None
    background: str | os.PathLike | np.ndarray | None = None


@dataclass
class CompressResult:
    """The written bundle, the chosen student's record and every student's record."""

    bundle: Bundle | None
    chosen: dict | None
    students: list[dict]
    summary_path: Path
