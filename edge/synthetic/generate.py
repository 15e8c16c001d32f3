"""Synthetic labelled datasets in the authors' layout (images/, forces/, meta.jsonl).

Samples come in grasps: one indenter pose held over ``frames_per_grasp`` frames at several
forces (sorted into ramp / hold / release phases). Each sample i is rendered with its own
generator seeded by (seed, i), so any subset can be regenerated identically.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..checks import check_fields, expect
from ..data.dataset import AuthorsDatasetWriter
from ..errors import DatasetError
from ..report.progress import progress
from ..typed_json import check
from .digit import ContactSpec, VirtualDigit, VirtualDigitOptions
from .indenters import STIFFNESS_CLASSES, get_indenter, paper_indenter_names
from .sampling import ForceDistribution, led_gain, sample_contact


@dataclass(frozen=True, slots=True)
class DatasetOptions:
    """What to generate.

    n: number of samples; seed: all randomness; indenters: names (default: the paper's 18);
    forces: force distribution (N); frames_per_grasp: samples sharing one pose;
    edge_fraction: share of grasps near a pad border; stiffness_classes: rigidity classes
    to draw from (None: each indenter's own); no_contact_fraction: share of 0 N frames;
    led_spread: relative std of the LED brightness per grasp; digit: renderer options;
    start_id: first sample number N; progress: draw a progress bar on stderr.
    """

    n: int = field(default=1000, metadata=check(ge=1, expected="an integer >= 1 (samples)"))
    seed: int = field(default=0, metadata=check(ge=0))
    indenters: tuple[str, ...] | None = None
    forces: ForceDistribution = field(default_factory=ForceDistribution)
    frames_per_grasp: int = field(default=8, metadata=check(ge=1))
    edge_fraction: float = field(default=0.15, metadata=check(ge=0, le=1))
    stiffness_classes: tuple[str, ...] | None = STIFFNESS_CLASSES
    no_contact_fraction: float = field(default=0.0, metadata=check(ge=0, le=1))
    led_spread: float = field(default=0.03, metadata=check(ge=0))
    digit: VirtualDigitOptions = field(default_factory=VirtualDigitOptions)
    start_id: int = field(default=0, metadata=check(ge=0))
    progress: bool = True

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(slots=True)
class DatasetSummary:
    """What was written: root, sample count, forces (N) range, counts per indenter /
    stiffness / location, wall time (s) and frames per second."""

    root: Path
    n: int
    force_min_n: float
    force_max_n: float
    per_indenter: dict[str, int]
    per_stiffness: dict[str, int]
    per_location: dict[str, int]
    seconds: float
    frames_per_s: float

    def as_dict(self) -> dict:
        from dataclasses import asdict

        d = asdict(self)
        d["root"] = str(self.root)
        return d


def _plan(options: DatasetOptions) -> list[tuple[int, str, ContactSpec | None, float, str, np.ndarray]]:
    """Per sample: (grasp, indenter, contact, force, phase, led_gain)."""
    rng = np.random.default_rng([options.seed, 1])
    names = list(options.indenters or paper_indenter_names())
    for nm in names:
        get_indenter(nm)
    k = max(int(options.frames_per_grasp), 1)
    plan: list[tuple[int, str, ContactSpec | None, float, str, np.ndarray]] = []
    g = 0
    while len(plan) < options.n:
        name = names[g % len(names)] if g < len(names) else str(rng.choice(names))  # every indenter appears
        contact = sample_contact(rng, name, options.edge_fraction, options.stiffness_classes)
        forces = np.sort(options.forces.sample(rng, k))
        nc = rng.random(k) < options.no_contact_fraction
        gain = led_gain(rng, options.led_spread)
        n_hold = max(1, k // 4)
        phases = ["ramp" if j % 2 == 0 else "release" for j in range(k - n_hold)] + ["hold"] * n_hold
        for j in range(k):
            if len(plan) >= options.n:
                break
            if nc[j]:
                plan.append((g, name, None, 0.0, "no_contact", gain))
            else:
                plan.append((g, name, contact, float(forces[j]), phases[j], gain))
        g += 1
    return plan


def _render(digit: VirtualDigit, options: DatasetOptions, i: int,
            entry: tuple[int, str, ContactSpec | None, float, str, np.ndarray]) -> tuple[np.ndarray, dict]:
    """Sample ``i`` of the plan: its frame (320 x 240 x 3 uint8 BGR) and metadata."""
    g, name, contact, force, phase, gain = entry
    out = digit.render(contact, force, led_gain=gain, rng=np.random.default_rng([options.seed, 2, i]))
    meta = dict(out.meta, phase=phase, grasp=g, seed=options.seed)
    meta.setdefault("indenter", name)
    meta.setdefault("stiffness", contact.stiffness if contact else None)
    meta.setdefault("location", "none")
    return out.frame, meta


def render_samples(options: DatasetOptions, indenters: tuple[str, ...]) -> list[tuple[int, np.ndarray, float, dict]]:
    """The samples of :func:`generate_dataset` with ``options`` whose indenter is one of
    ``indenters`` (e.g. a split's test part), rendered alone: (sample number N, frame 320 x 240
    x 3 uint8 BGR, force N, metadata), bit for bit what ``generate_dataset`` writes for them."""
    expect(options, DatasetOptions, "render_samples.options")
    digit = VirtualDigit(replace(options.digit, seed=options.seed))
    out = []
    for i, entry in enumerate(_plan(options)):
        if entry[1] in indenters:
            frame, meta = _render(digit, options, i, entry)
            out.append((options.start_id + i, frame, entry[3], meta))
    return out


def generate_dataset(root: str | os.PathLike, options: DatasetOptions = DatasetOptions()) -> DatasetSummary:
    """Render ``options.n`` samples into ``root`` (authors' layout + meta.jsonl).

    Refuses a root that already holds images/ (no silent mixing of datasets).
    """
    expect(root, (str, os.PathLike), "generate_dataset.root", "an output folder path", nonempty=True)
    expect(options, DatasetOptions, "generate_dataset.options")
    root = Path(root)
    if (root / "images").is_dir() and any((root / "images").iterdir()):
        raise DatasetError(f"{root}: already holds images/; choose an empty output folder")
    digit = VirtualDigit(replace(options.digit, seed=options.seed))
    plan = _plan(options)
    per_ind: dict[str, int] = {}
    per_stiff: dict[str, int] = {}
    per_loc: dict[str, int] = {}
    forces = []
    t0 = time.perf_counter()
    with AuthorsDatasetWriter(root, start_id=options.start_id) as writer:
        for i, entry in progress(list(enumerate(plan)), desc="synth", enabled=options.progress):
            name, force = entry[1], entry[3]
            frame, meta = _render(digit, options, i, entry)
            writer.write(frame, force, meta=meta, n=options.start_id + i)
            per_ind[name] = per_ind.get(name, 0) + 1
            per_stiff[str(meta["stiffness"])] = per_stiff.get(str(meta["stiffness"]), 0) + 1
            per_loc[meta["location"]] = per_loc.get(meta["location"], 0) + 1
            forces.append(force)
    dt = time.perf_counter() - t0
    return DatasetSummary(root=root, n=len(plan), force_min_n=float(min(forces)), force_max_n=float(max(forces)),
                          per_indenter=per_ind, per_stiffness=per_stiff, per_location=per_loc, seconds=dt,
                          frames_per_s=len(plan) / dt if dt > 0 else float("inf"))
