"""The virtual DIGIT: physically grounded synthetic tactile frames with known normal force,
grasp-sequence frame source, synthetic datasets in the authors' layout, indenter splits."""

from .digit import ContactSpec, SyntheticFrame, VirtualDigit, VirtualDigitOptions
from .dome import DomeOptions, dome_height_mm
from .generate import DatasetOptions, DatasetSummary, generate_dataset, render_samples
from .indenters import (
                        EXTRA_INDENTERS,
                        INDENTERS,
                        PAPER_INDENTERS,
                        STIFFNESS_CLASSES,
                        Indenter,
                        get_indenter,
                        paper_indenter_names,
)
from .mechanics import GelOptions
from .sampling import ForceDistribution, sample_contact
from .shading import Led, ShadingOptions
from .source import PHASES, VirtualDigitSource
from .splits import PAPER_SPLIT_SEEDS, IndenterSplit, indenter_split, paper_split, split_ids

__all__ = [
    "ContactSpec", "DatasetOptions", "DatasetSummary", "DomeOptions", "EXTRA_INDENTERS", "ForceDistribution",
    "GelOptions", "INDENTERS", "Indenter", "IndenterSplit", "Led", "PAPER_INDENTERS", "PAPER_SPLIT_SEEDS", "PHASES",
    "STIFFNESS_CLASSES", "ShadingOptions", "SyntheticFrame", "VirtualDigit", "VirtualDigitOptions",
    "VirtualDigitSource", "dome_height_mm", "generate_dataset", "render_samples", "get_indenter", "indenter_split",
    "paper_indenter_names", "paper_split", "sample_contact", "split_ids",
]
