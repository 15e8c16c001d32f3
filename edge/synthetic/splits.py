"""Splits by indenter, as the paper's S1/S2/S3: 14 train / 2 validation / 2 test indenters.

A split is a seeded random partition of indenter names; samples are assigned by the
'indenter' field of their metadata, so no indenter appears in two parts.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np

from ..checks import check_fields
from .indenters import paper_indenter_names

#: Seeds of the three paper-like splits.
PAPER_SPLIT_SEEDS = {"S1": 1, "S2": 2, "S3": 3}


@dataclass(frozen=True, slots=True)
class IndenterSplit:
    """Indenter names of each part."""

    name: str
    train: tuple[str, ...]
    val: tuple[str, ...]
    test: tuple[str, ...]

    def __post_init__(self) -> None:
        check_fields(self)

    def part_of(self, indenter: str) -> str | None:
        """'train' / 'val' / 'test' for an indenter, None if the split does not hold it."""
        for part in ("train", "val", "test"):
            if indenter in getattr(self, part):
                return part
        return None


def indenter_split(indenters: Iterable[str], seed: int, n_val: int = 2, n_test: int = 2,
                   name: str = "") -> IndenterSplit:
    """Seeded random partition of ``indenters`` into train / val (n_val) / test (n_test)."""
    names = sorted(set(indenters))
    if len(names) < n_val + n_test + 1:
        raise ValueError(f"{len(names)} indenters cannot give {n_val} val + {n_test} test + >= 1 train")
    order = np.random.default_rng(seed).permutation(len(names))
    picked = [names[i] for i in order]
    return IndenterSplit(name or f"seed{seed}", tuple(sorted(picked[n_val + n_test:])),
                         tuple(sorted(picked[:n_val])), tuple(sorted(picked[n_val:n_val + n_test])))


def paper_split(name: str) -> IndenterSplit:
    """S1, S2 or S3 over the 18 paper-like indenters (14 / 2 / 2)."""
    if name not in PAPER_SPLIT_SEEDS:
        raise ValueError(f"split {name!r}: expected one of {sorted(PAPER_SPLIT_SEEDS)}")
    return indenter_split(paper_indenter_names(), PAPER_SPLIT_SEEDS[name], name=name)


def split_ids(meta: Mapping[int, dict], split: IndenterSplit) -> dict[str, list[int]]:
    """Sample ids per part ('train', 'val', 'test') from per-sample metadata (id -> dict with
    'indenter', e.g. ``AuthorsDataset(root).meta``). Samples of indenters outside the split
    go to 'other'."""
    out: dict[str, list[int]] = {"train": [], "val": [], "test": [], "other": []}
    for n in sorted(meta):
        ind = meta[n].get("indenter")
        part = split.part_of(ind) if ind is not None else None
        out[part or "other"].append(n)
    return out
