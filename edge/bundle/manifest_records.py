"""The manifest's sections that say how the bundle was made and measured: quantization, parity,
error figures and the error report, provenance; edge/bundle/manifest.py re-exports them."""

from __future__ import annotations

import math
from dataclasses import dataclass, field


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
