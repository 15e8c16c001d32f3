"""The manifest's sections that say what the graph is and reads: the variant, precision, each
input (kind, shape, how a frame is reduced to it), the output, the architecture and the depth
record of depth bundles; edge/bundle/manifest.py re-exports them."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Literal

from ..frames import FRAME_COLS, FRAME_ROWS
from ..typed_json import check


class _StrEnum(str, enum.Enum):
    """A str-valued enum that prints as its value (f-strings, str(), JSON)."""

    def __str__(self) -> str:
        return str(self.value)

    def __format__(self, spec: str) -> str:
        return format(str(self.value), spec)


class Variant(_StrEnum):
    """The paper's model variants (what the graph reads)."""

    RGBMOD = "rgbmod"
    D = "d"
    DMOD = "dmod"
    RGBMOD_D = "rgbmod+d"

    @property
    def needs_depth(self) -> bool:
        """True when the graph takes a depth image (the runtime builds the depth stage)."""
        return self is not Variant.RGBMOD

    @property
    def needs_rgb(self) -> bool:
        """True when the graph takes the BGR frame."""
        return self in (Variant.RGBMOD, Variant.RGBMOD_D)


class Precision(_StrEnum):
    """Numeric precision of the graph."""

    FP32 = "fp32"
    FP16 = "fp16"
    INT8_STATIC = "int8-static"
    INT8_DYNAMIC = "int8-dynamic"


class InputKind(_StrEnum):
    """What a graph input carries."""

    RGB = "rgb"  # the BGR frame, (N, 320, 240, 3) uint8
    DEPTH = "depth"  # the 8-bit depth image, (N, 320, 240, 1) uint8


class Reduction(_StrEnum):
    """How a full-resolution frame is reduced to the network's input (edge/gate/reduce.py)."""

    NONE = "none"  # the graph takes the full-resolution frame
    AREA = "area"  # one k x k box average (OpenCV INTER_AREA), rounded half to even
    AREA_2X_STEPS = "area-2x-steps"  # log2(k) exact 2x2 box averages, each rounded half up


@dataclass
class FrameReduction:
    """How a 320 x 240 frame becomes the network input: ``method`` and integer ``factor`` k
    (the input is (320/k, 240/k)); ``none`` with k = 1 for full-resolution graphs."""

    method: Reduction = Reduction.NONE
    factor: int = 1

    def __post_init__(self) -> None:
        self.method = Reduction(self.method)

    def check(self) -> None:
        if isinstance(self.factor, bool) or not isinstance(self.factor, int) or self.factor < 1:
            raise ValueError(f"reduction.factor {self.factor!r}: expected an integer >= 1")
        if (self.method is Reduction.NONE) != (self.factor == 1):
            raise ValueError(f"reduction {self.method.value!r} with factor {self.factor}: 'none' goes with "
                             "factor 1 and a reduction with a factor >= 2")
        if FRAME_ROWS % self.factor or FRAME_COLS % self.factor:
            raise ValueError(f"reduction.factor {self.factor}: must divide the {FRAME_ROWS} x {FRAME_COLS} frame")
        if self.method is Reduction.AREA_2X_STEPS and self.factor & (self.factor - 1):
            raise ValueError(f"reduction 'area-2x-steps' needs a power-of-two factor, got {self.factor}")


VARIANTS = tuple(v.value for v in Variant)


DEPTH_VARIANTS = tuple(v.value for v in Variant if v.needs_depth)


PRECISIONS = tuple(p.value for p in Precision)


@dataclass
class InputSpec:
    """One graph input, the network input record: uint8 NHWC (batch, rows, cols, channels),
    -1 = the dynamic batch; ``reduction`` says how a 320 x 240 frame becomes it (format 3;
    ``none``: the graph takes the full frame)."""

    name: str
    kind: InputKind
    shape: list[int]
    dtype: str = "uint8"
    layout: str = "NHWC"
    colour_order: str = "BGR"  # 'BGR' for rgb inputs, 'GRAY' for depth
    scaling: str = "x / 255 inside the graph"
    reduction: FrameReduction = field(default_factory=FrameReduction)

    def __post_init__(self) -> None:
        self.kind = InputKind(self.kind)

    @property
    def channels(self) -> int:
        return 3 if self.kind is InputKind.RGB else 1

    @property
    def network_shape(self) -> tuple[int, int, int]:
        """(rows, cols, channels) the graph reads: the frame reduced by ``reduction.factor``."""
        k = self.reduction.factor
        return FRAME_ROWS // k, FRAME_COLS // k, self.channels

    def check(self) -> None:
        self.reduction.check()
        want = [-1, *self.network_shape]
        if self.shape != want:
            raise ValueError(f"input {self.name!r} ({self.kind.value}) has shape {self.shape}; the frame contract "
                             f"reduced by {self.reduction.method.value!r} x{self.reduction.factor} is {want}")
        if self.dtype != "uint8" or self.layout != "NHWC":
            raise ValueError(f"input {self.name!r}: dtype {self.dtype} layout {self.layout}; expected uint8 NHWC")
        want_order = "BGR" if self.kind is InputKind.RGB else "GRAY"
        if self.colour_order != want_order:
            raise ValueError(f"input {self.name!r}: colour_order {self.colour_order!r}; expected {want_order!r}")


@dataclass
class ModelOutputSpec:
    """The graph output: one force in newtons per frame."""

    name: str = "force_n"
    shape: list[int] = field(default_factory=lambda: [-1])
    dtype: str = "float32"
    unit: str = "N"

    def check(self) -> None:
        if self.unit != "N" or self.dtype != "float32":
            raise ValueError(f"output {self.name!r}: {self.dtype} in {self.unit!r}; expected float32 in 'N'")


def stage_channels(width: float) -> tuple[int, int, int, int]:
    """Channel counts of layer1..layer4 of the ResNet-18 family for a width multiplier (64, 128, 256,
    512 at 1.0; at least 4 each): what export builds and what ``bundle verify`` checks a graph against."""
    c1, c2, c3, c4 = (max(4, int(round(base * float(width)))) for base in (64, 128, 256, 512))
    return c1, c2, c3, c4


@dataclass
class Architecture:
    """The network: ResNet-18 family, width multiplier, input scale and residual blocks per
    stage (``blocks``: ResNet-18's [2, 2, 2, 2], what a manifest without the field means;
    fewer for cheaper networks)."""

    family: str = "resnet18"
    width: float = 1.0
    input_scale: float = 1.0
    network_input_hw: list[int] = field(default_factory=lambda: [FRAME_ROWS, FRAME_COLS])
    head_folded: bool = False
    preprocess_folded: bool = False
    gmacs: float | None = None
    params: int | None = None
    opset: int | None = None
    macs_by_op: dict[str, int] = field(default_factory=dict)
    blocks: list[int] = field(default_factory=lambda: [2, 2, 2, 2])

    def channels(self) -> tuple[int, int, int, int]:
        """Channels of layer1..layer4 at this width (64, 128, 256, 512 at 1.0; at least 4 each)."""
        return stage_channels(self.width)

    def check(self) -> None:
        if not 0 < self.width <= 4 or not 0 < self.input_scale <= 1:
            raise ValueError(f"width {self.width} / input_scale {self.input_scale} out of range (0, 4] / (0, 1]")
        if len(self.blocks) != 4 or not all(1 <= b <= 8 for b in self.blocks):
            raise ValueError(f"blocks {self.blocks}: expected four residual-block counts per stage, each 1..8, "
                             "e.g. [2, 2, 2, 2] (ResNet-18)")
        if len(self.network_input_hw) != 2 or min(self.network_input_hw) < 1:
            raise ValueError(f"network_input_hw {self.network_input_hw}: expected [rows, cols] >= 1")


@dataclass
class DepthRecord:
    """How the depth images the model was trained on were made; the runtime rebuilds it.

    ``mapping`` is a colour->normal ``.npz`` path, or ``package:FILE`` for a file shipped in
    ``tactile_force/edge/assets``. ``reduction`` with factor k > 1: the depth was made at the
    network resolution (colour->normal and the Poisson solve on the frame reduced to
    320/k x 240/k by that method; heights in full-resolution pixels, docs/depth.md); ``none``
    x1 (the default, and every bundle written before the field existed): at full resolution.
    """

    mapping: str
    mode: Literal["exact", "paper"] = "exact"  # DepthOptions.mode
    levels_per_px: float | None = field(default=None, metadata=check(gt=0))  # DepthOptions fields of the same name
    paper_scale: float | None = field(default=None, metadata=check(gt=0))
    mapping_sha256: str = ""
    mask: str = ""
    #: The depth grid: the frame reduced by ``reduction`` (factor k: 320/k x 240/k), where the
    #: colour->normal mapping and the Poisson solve ran; ``none`` x1 = full resolution.
    reduction: FrameReduction = field(default_factory=FrameReduction)

    def check(self) -> None:
        """Raise ValueError when the depth grid is not a valid reduction, or paper mode is not
        at full resolution."""
        self.reduction.check()
        if self.reduction.factor > 1 and self.mode == "paper":
            raise ValueError(f"depth.reduction x{self.reduction.factor}: paper mode runs at full resolution (none x1)")

    @property
    def downscale(self) -> int:
        """The depth grid's reduction factor k (1: full resolution)."""
        return self.reduction.factor

    @property
    def grid_hw(self) -> tuple[int, int]:
        """(rows, cols) of the depth images the model reads: 320/k x 240/k."""
        return FRAME_ROWS // self.reduction.factor, FRAME_COLS // self.reduction.factor
