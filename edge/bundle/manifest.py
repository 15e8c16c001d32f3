"""The bundle manifest: ONE typed, versioned record that export/ writes and edge/ reads.

``model.json`` beside ``model.onnx`` holds a :class:`Manifest`. :func:`manifest_from_json`
validates every field from its type (errors name the dotted field path) and migrates
format 1 manifests; :meth:`Manifest.to_json` writes the current format. No module reads
a manifest's raw dict: they all use these dataclasses.

Format history
--------------
1
    Nested free-form dicts (``architecture``, ``error``, ``parity``, ``provenance``,
    ``preprocessing_in_graph``); the depth record inside ``architecture``.
2
    Typed sections; ``depth`` and ``error`` promoted and renamed (``vs_ground_truth``
    -> ``error.vs_truth`` / ``error.fp32_vs_truth``); ``force_calibration`` and
    ``data_stats`` added; later ``interval`` (optional).
3
    Each input records the network input it feeds and how a full-resolution frame is
    reduced to it (``inputs[].reduction``: method and factor; edge/gate/reduce.py): a compact
    graph starts at the network resolution (e.g. 80 x 60) and the runtime reduces each frame
    once. Format-2 bundles migrate as full-resolution graphs (reduction ``none``).
"""

from __future__ import annotations

import enum
import json
import math
from dataclasses import dataclass, field
from pathlib import PurePosixPath, PureWindowsPath
from typing import Any, Literal

from ..errors import BundleError
from ..frames import FRAME_COLS, FRAME_ROWS
from ..typed_json import TypedJsonError, check, from_json, to_json
from .data_stats import DataStats
from .force_calibration import ForceCalibration
from .interval import ForceInterval

FORMAT_VERSION = 3


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


@dataclass
class Quantization:
    """How a quantized graph was made (absent for fp32)."""

    format: str
    activations: str = ""
    weights: str = ""
    io: str = ""
    per_channel: bool = False
    method: str = ""
    percentile: float | None = None
    histogram_bins: int | None = None
    calibration_data: str = ""
    calibration_frames: int = 0
    kept_float: list[str] = field(default_factory=list)
    final_layer: str = ""
    tool: str = ""
    op_counts: dict[str, int] = field(default_factory=dict)


@dataclass
class Parity:
    """ONNX Runtime vs the torch reference on the same frames, measured at export (N)."""

    max_abs_diff_n: float
    frames: int
    mean_abs_diff_n: float = 0.0
    data: str = ""
    tolerance_n: float = 1e-4
    reference: str = "torch eager, unfolded head"
    runtime: str = "onnxruntime CPUExecutionProvider"


@dataclass
class ErrorFigures:
    """The paper's metrics against reference forces (edge.metrics.ErrorStats): RE and MAE (N).

    ``None`` (NaN in memory) where not measurable, e.g. RE when every reference is ~0 N.
    """

    n: int
    re_mean: float | None
    re_std: float | None
    mae_mean: float | None
    mae_std: float | None
    n_excluded_re: int = 0


@dataclass
class DiffFigures(ErrorFigures):
    """Differences to the fp32 graph's output (N), plus RE/MAE taking fp32 as the reference."""

    max_abs_diff_n: float = 0.0
    mean_abs_diff_n: float = 0.0


@dataclass
class ErrorReport:
    """Error measured when the bundle was made, on ``frames`` frames of ``data``."""

    data: str = ""
    frames: int = 0
    same_frames_as_calibration: bool = False
    vs_truth: ErrorFigures | None = None  # this graph vs the labels
    fp32_vs_truth: ErrorFigures | None = None  # the fp32 graph it came from vs the labels
    vs_fp32: DiffFigures | None = None  # this graph vs the fp32 graph
    vs_teacher: ErrorFigures | None = None  # a distilled student vs its teacher

    def score(self) -> float:
        """Lower is more accurate: RE vs the labels, inf when not measured (the ladder's key)."""
        re = self.vs_truth.re_mean if self.vs_truth is not None else None
        if re is None or not math.isfinite(re):
            return math.inf
        return re


@dataclass
class SourceRef:
    """Another bundle this one was made from."""

    bundle: str
    sha256: str


@dataclass
class Provenance:
    """Where the weights came from and how the bundle was made."""

    checkpoint: str = ""
    checkpoint_sha256: str = ""
    checkpoint_format: str = ""
    trained_on: str = "unknown"
    note: str = ""
    epochs: int | None = None
    torch: str = ""
    exporter: str = ""
    export_seconds: float | None = None
    quantized_from: SourceRef | None = None
    quantize_seconds: float | None = None
    calibrated_from: SourceRef | None = None
    teacher: dict[str, str | float | int] = field(default_factory=dict)
    host: str = ""
    extra: dict[str, str | float | int | bool] = field(default_factory=dict)


@dataclass
class Manifest:
    """The bundle manifest (``model.json``), format 3.

    Sections left ``None`` were not measured or do not apply (``quantization`` for fp32,
    ``depth`` for RGBmod, ``force_calibration`` until ``tactile-force calibrate-force``,
    ``interval`` until a verb or ``benchmarks.interval_fit`` fits one on labelled data).
    """

    variant: Variant
    precision: Precision
    inputs: list[InputSpec]
    output: ModelOutputSpec = field(default_factory=ModelOutputSpec)
    name: str = ""
    format_version: int = FORMAT_VERSION
    sha256: str = ""
    onnx_file: str = "model.onnx"
    preprocessing: list[str] = field(default_factory=list)
    architecture: Architecture = field(default_factory=Architecture)
    depth: DepthRecord | None = None
    quantization: Quantization | None = None
    parity: Parity | None = None
    error: ErrorReport | None = None
    provenance: Provenance = field(default_factory=Provenance)
    force_calibration: ForceCalibration | None = None
    data_stats: DataStats | None = None
    #: why ``data_stats`` is None: the bundle's out-of-distribution and contact-size checks are
    #: off (the tool that wrote it saw no frames); "" with data_stats None: not recorded (older bundles)
    data_stats_missing: str = ""
    #: the error bar of every reading (edge/bundle/interval.py); None: readings' intervals are unknown
    interval: ForceInterval | None = None
    created_by: str = "tactile-force"

    def __post_init__(self) -> None:
        self.variant = Variant(self.variant)  # accept the plain strings too
        self.precision = Precision(self.precision)

    @property
    def needs_depth(self) -> bool:
        return self.variant.needs_depth

    def input(self, kind: InputKind) -> InputSpec | None:
        """The input of ``kind``, or None when the graph has none."""
        return next((s for s in self.inputs if s.kind is kind), None)

    def error_score(self) -> float:
        """RE vs the labels recorded at build time; inf when not measured."""
        return self.error.score() if self.error is not None else math.inf

    def check(self) -> None:
        if self.format_version != FORMAT_VERSION:
            raise ValueError(f"format_version {self.format_version}; this package writes {FORMAT_VERSION}")
        check_onnx_file_name(self.onnx_file)
        kinds = [s.kind for s in self.inputs]
        wanted = ((InputKind.RGB, self.variant.needs_rgb), (InputKind.DEPTH, self.variant.needs_depth))
        want = [k for k, needed in wanted if needed]
        if sorted(k.value for k in kinds) != sorted(k.value for k in want):
            raise ValueError(f"inputs: variant {self.variant.value!r} needs inputs of kind "
                             f"{[k.value for k in want]}, the manifest lists {[k.value for k in kinds]}")
        if len({s.name for s in self.inputs}) != len(self.inputs):
            raise ValueError("inputs: two inputs share a name")
        if self.precision is Precision.FP32 and self.quantization is not None:
            raise ValueError("quantization: present on an fp32 bundle")
        check_bundle_name(self.name)
        if self.depth is not None and not self.variant.needs_depth:
            raise ValueError(f"depth: a depth record on variant {self.variant.value!r}, which reads no depth image; "
                             "expected none (depth records belong to d, dmod and rgbmod+d bundles)")
        if self.depth is not None:
            self.depth.check()
            spec = self.input(InputKind.DEPTH)
            if spec is not None and spec.shape[1:3] != list(self.depth.grid_hw):
                raise ValueError(f"depth: made on a {list(self.depth.grid_hw)} grid (reduction "
                                 f"x{self.depth.downscale}) but the graph's depth input is {spec.shape[1:3]}")

    def to_json(self) -> str:
        """The manifest as pretty-printed JSON text (the current format)."""
        return json.dumps(to_json(self), indent=2, allow_nan=False) + "\n"


#: The longest bundle ``name`` (characters): a name is shown on every line that names the bundle.
MAX_NAME_CHARS = 128


def check_bundle_name(name: str) -> None:
    """Raise ValueError unless ``name`` is a plain name ("" or at most :data:`MAX_NAME_CHARS`
    characters, no path separator, no control character or newline, not ``.`` / ``..``): it
    is printed in every reading's log line and used as a folder name by the tools."""
    if not name:
        return
    bad = next((c for c in name if ord(c) < 32 or ord(c) == 127 or c in "/\\"), None)
    if bad is not None or name in (".", "..") or len(name) > MAX_NAME_CHARS or name.strip() != name:
        why = (f"holds {bad!r}" if bad is not None else f"is {len(name)} characters" if len(name) > MAX_NAME_CHARS
               else "is not a plain name")
        raise ValueError(f"name {name[:60]!r}{'...' if len(name) > 60 else ''} {why}; expected a plain name (no path "
                         f"separator, control character or newline, no leading or trailing space, at most "
                         f"{MAX_NAME_CHARS} characters)")


def check_onnx_file_name(name: str) -> None:
    """Raise ValueError unless ``name`` is a plain file name inside the bundle folder."""
    if (not name or name in (".", "..") or PurePosixPath(name).name != name or PureWindowsPath(name).name != name
            or not name.endswith(".onnx")):
        raise ValueError(f"onnx_file {name!r}: expected a plain file name ending in .onnx inside the bundle folder")


def manifest_from_json(raw: object, source: str = "model.json") -> Manifest:
    """Validate a parsed manifest (format 1, 2 or 3) and return it as format 3.

    Parameters
    ----------
    raw
        The parsed JSON object.
    source
        Where it came from, named in every error.

    Returns
    -------
    Manifest

    Raises
    ------
    BundleError
        Naming the field that is missing, unknown, of the wrong type or inconsistent.
    """
    if not isinstance(raw, dict):
        raise BundleError(f"{source}: not a tactile-force manifest (expected a JSON object, got {type(raw).__name__})")
    version = raw.get("format_version")
    try:
        if version == 1:
            raw = _migrate_v1(raw)
        elif version == 2:  # full-resolution graphs: every input's reduction is 'none' (the default)
            raw = {**raw, "format_version": FORMAT_VERSION}
        elif version != FORMAT_VERSION:
            raise BundleError(f"{source}: format_version {version!r}; this package reads 1, 2 and {FORMAT_VERSION}")
        return from_json(Manifest, raw)
    except TypedJsonError as exc:
        raise BundleError(f"{source}: {exc}") from None
    except BundleError:
        raise
    except (TypeError, ValueError, KeyError, AttributeError) as exc:  # malformed format-1 sections
        raise BundleError(f"{source}: not a valid format-1 manifest ({type(exc).__name__}: {exc})") from None


def _pick(d: Any, cls: type, *, rename: dict[str, str] | None = None) -> dict[str, Any]:
    """Keep the keys of ``d`` that name fields of dataclass ``cls`` (format-1 migration)."""
    from dataclasses import fields

    if not isinstance(d, dict):
        raise TypeError(f"expected an object for {cls.__name__}, got {type(d).__name__}")
    names = {f.name for f in fields(cls)}
    ren: dict[str, str] = rename or {}
    out: dict[str, Any] = {}
    for key, value in d.items():
        name = ren.get(str(key), str(key))
        if name in names:
            out[name] = value
    return out


def _migrate_v1(raw: dict[str, Any]) -> dict[str, Any]:
    """Format 1 (free-form dicts) -> format 2 (typed sections)."""
    out: dict[str, Any] = {k: raw[k] for k in ("variant", "precision", "name", "sha256", "onnx_file", "created_by")
                           if k in raw}
    out["format_version"] = FORMAT_VERSION
    inputs = raw.get("inputs")
    if isinstance(inputs, list) and all(isinstance(s, dict) for s in inputs):
        inputs = [{k: v for k, v in s.items() if k in ("name", "kind", "shape", "dtype", "layout", "colour_order",
                                                        "scaling")} for s in inputs]
    out["inputs"] = inputs  # anything else: the typed reader names the field
    output = raw.get("output")
    if isinstance(output, dict):
        out["output"] = {k: v for k, v in output.items() if k in ("name", "shape", "dtype", "unit")}
    elif output is not None:
        out["output"] = output
    out["preprocessing"] = raw.get("preprocessing_in_graph", [])
    arch = dict(raw.get("architecture") or {})
    depth = arch.pop("depth", None)
    out["architecture"] = _pick(arch, Architecture)
    if depth and out.get("variant") != Variant.RGBMOD.value:  # format 1 kept one in every architecture
        out["depth"] = _pick(depth, DepthRecord)
    if raw.get("quantization"):
        out["quantization"] = _pick(raw["quantization"], Quantization)
    if raw.get("parity"):
        out["parity"] = _pick(raw["parity"], Parity)
    err = raw.get("error") or {}
    if err:
        rep: dict[str, Any] = _pick(err, ErrorReport)
        truth = err.get("vs_ground_truth") or {}
        if truth.get("quantized"):
            rep["vs_truth"] = _pick(truth["quantized"], ErrorFigures)
            if truth.get("fp32"):
                rep["fp32_vs_truth"] = _pick(truth["fp32"], ErrorFigures)
        elif truth.get("fp32"):
            rep["vs_truth"] = _pick(truth["fp32"], ErrorFigures)
        if err.get("vs_fp32"):
            rep["vs_fp32"] = _pick(err["vs_fp32"], DiffFigures)
        out["error"] = rep
    prov = dict(raw.get("provenance") or {})
    known = _pick(prov, Provenance)
    extra = {k: v for k, v in prov.items() if k not in known and isinstance(v, (str, int, float, bool))}
    known.pop("extra", None)
    if extra:
        known["extra"] = extra
    out["provenance"] = known
    return out
