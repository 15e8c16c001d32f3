"""The virtual DIGIT: physically grounded synthetic tactile frames with known normal force,
grasp-sequence frame source, synthetic datasets in the authors' layout, indenter splits."""

from .digit import ContactSpec, SyntheticFrame, VirtualDigit, VirtualDigitOptions
from .dome import DomeOptions, dome_height_mm
from .generate import DatasetOptions, DatasetSummary, generate_dataset
from .indenters import (EXTRA_INDENTERS, INDENTERS, PAPER_INDENTERS, STIFFNESS_CLASSES, Indenter, get_indenter,
                        paper_indenter_names)
from .mechanics import GelOptions
from .sampling import ForceDistribution, sample_contact
from .shading import Led, ShadingOptions
from .source import PHASES, VirtualDigitSource
from .splits import PAPER_SPLIT_SEEDS, IndenterSplit, indenter_split, paper_split, split_ids

__all__ = [name for name in dir() if not name.startswith("_")]
