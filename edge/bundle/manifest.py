"""The bundle manifest: ONE typed, versioned record that export/ writes and edge/ reads.

``model.json`` beside ``model.onnx`` holds a :class:`Manifest`. :func:`manifest_from_json`
validates every field from its type (errors name the dotted field path) and migrates
format 1 manifests; :meth:`Manifest.to_json` writes the current format. No module reads
a manifest's raw dict: they all use these dataclasses. The sections' records live in
``manifest_graph`` (what the graph is and reads) and ``manifest_records`` (how it was made
and measured), the format version and the name checks in ``manifest_format``, the format-1
migration in ``manifest_migrate``; every one is importable from here.

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

import json
import math
from dataclasses import dataclass, field

from ..errors import BundleError
from ..typed_json import TypedJsonError, from_json, to_json
from .data_stats import DataStats
from .force_calibration import ForceCalibration
from .interval import ForceInterval
from .manifest_format import FORMAT_VERSION, MAX_NAME_CHARS, check_bundle_name, check_onnx_file_name
from .manifest_graph import (
    DEPTH_VARIANTS,
    PRECISIONS,
    VARIANTS,
    Architecture,
    DepthRecord,
    FrameReduction,
    InputKind,
    InputSpec,
    ModelOutputSpec,
    Precision,
    Reduction,
    Variant,
)
from .manifest_migrate import migrate_v1
from .manifest_records import DiffFigures, ErrorFigures, ErrorReport, Parity, Provenance, Quantization, SourceRef

#: every section's record is importable from here (the records live in manifest_graph.py,
#: manifest_records.py; the format and name checks in manifest_format.py)
__all__ = ["Architecture", "DEPTH_VARIANTS", "DepthRecord", "DiffFigures", "ErrorFigures", "ErrorReport",
           "FORMAT_VERSION", "FrameReduction", "InputKind", "InputSpec", "MAX_NAME_CHARS", "Manifest",
           "ModelOutputSpec", "PRECISIONS", "Parity", "Precision", "Provenance", "Quantization", "Reduction",
           "SourceRef", "VARIANTS", "Variant", "check_bundle_name", "check_onnx_file_name",
           "manifest_from_json"]


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
            raw = migrate_v1(raw)
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


