"""tactile_force.edge: the robot-side runtime (numpy + onnxruntime + OpenCV + SciPy, never torch).

Data flow: frame source -> contact gate -> [depth stage for D/Dmod/RGBmod+D] -> ONNX
inference -> ForceReading. See docs/architecture.md.

Importing this package loads the contracts (frames, readings, manifest, bundles, errors)
and nothing else; every other name below is imported on first use, so an RGBmod runtime
never loads the depth stage, the virtual DIGIT or a device library.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from . import _moved
from .bundle.manifest import DEPTH_VARIANTS, PRECISIONS, VARIANTS, InputKind, Manifest, Precision, Variant
from .bundle.store import Bundle, load_bundle, read_manifest, sha256_file, write_bundle
from .errors import (
    AcceleratorUnavailableError,
    ArgumentTypeError,
    BundleError,
    DatasetError,
    FrameError,
    MissingExtraError,
    OptionsError,
    SceneError,
    SourceError,
    TactileForceError,
)
from .frames import FRAME_SHAPE, FrameSource, SourceStats, TimedFrame, check_frame
from .reading import MAX_VALID_FORCE_N, MIN_VALID_FORCE_N, Flags, ForceReading, IntervalState, StageLatency

_moved.install()  # the flat module paths of earlier versions (tactile_force.edge.manifest, ...) keep working

#: name -> submodule that defines it (imported on first access)
_LAZY = {
    # runtime
    "ContactGate": "gate", "GateOptions": "gate", "GateResult": "gate",
    "OnnxForceModel": "model", "LadderChoice": "model.ladder", "choose_bundle": "model.ladder",
    "CsvWriter": "outputs", "JsonlWriter": "outputs", "StdoutWriter": "outputs",
    "ForceRuntime": "runtime", "RuntimeOptions": "runtime", "RuntimeStats": "runtime", "Sensor": "runtime",
    "plan_stages": "runtime",
    "Scene": "scene", "build_scene": "scene", "default_bundle_path": "scene", "describe_scene": "scene",
    "load_scene": "scene", "shipped_bundles": "scene",
    "CameraSource": "sources", "ReplayFolderSource": "sources", "StreamLost": "sources", "VideoFileSource": "sources",
    "load_background": "sources", "open_v4l2": "sources",
    "ForceCalibration": "bundle.force_calibration", "DataStats": "bundle.data_stats",
    "ForceInterval": "bundle.interval", "fit_interval": "bundle.interval",
    # labelled data and metrics
    "AuthorsDataset": "data.dataset", "AuthorsDatasetWriter": "data.dataset", "Sample": "data.dataset",
    "ErrorReport": "data.metrics", "ErrorStats": "data.metrics", "error_report": "data.metrics",
    "error_stats": "data.metrics",
    "relative_error": "data.metrics",
    # depth stage (D / Dmod / RGBmod+D only)
    "DepthOptions": "depth", "DepthResult": "depth", "DepthStage": "depth", "MaxDeformationBaseline": "depth",
    "NormalLUT": "depth",
    # the virtual DIGIT (demo, tests, benchmarks)
    "ContactSpec": "synthetic", "DatasetOptions": "synthetic", "DatasetSummary": "synthetic",
    "IndenterSplit": "synthetic", "SyntheticFrame": "synthetic", "VirtualDigit": "synthetic",
    "VirtualDigitOptions": "synthetic", "VirtualDigitSource": "synthetic", "generate_dataset": "synthetic",
    "indenter_split": "synthetic", "paper_split": "synthetic", "split_ids": "synthetic",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'tactile_force.edge' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))


__all__ = [
    "ForceInterval", "IntervalState", "fit_interval",
    "AcceleratorUnavailableError", "ArgumentTypeError", "AuthorsDataset", "AuthorsDatasetWriter", "Bundle",
    "BundleError",
    "CameraSource", "ContactGate", "ContactSpec", "CsvWriter", "DEPTH_VARIANTS", "DataStats", "DatasetError",
    "DatasetOptions", "DatasetSummary", "DepthOptions", "DepthResult", "DepthStage", "ErrorReport", "ErrorStats",
    "FRAME_SHAPE", "Flags", "ForceCalibration", "ForceReading", "ForceRuntime", "FrameError", "FrameSource",
    "GateOptions", "GateResult", "IndenterSplit", "InputKind", "JsonlWriter", "LadderChoice", "MAX_VALID_FORCE_N",
    "MIN_VALID_FORCE_N", "Manifest", "MaxDeformationBaseline", "MissingExtraError", "NormalLUT", "OnnxForceModel",
    "OptionsError", "PRECISIONS", "Precision", "ReplayFolderSource", "RuntimeOptions", "RuntimeStats", "Sample",
    "Scene",
    "SceneError", "Sensor", "SourceError", "SourceStats", "StageLatency", "StdoutWriter", "StreamLost",
    "SyntheticFrame", "TactileForceError", "TimedFrame", "VARIANTS", "Variant", "VideoFileSource", "VirtualDigit",
    "VirtualDigitOptions", "VirtualDigitSource", "build_scene", "check_frame", "choose_bundle",
    "default_bundle_path", "describe_scene", "error_report", "error_stats", "generate_dataset", "indenter_split",
    "load_background", "load_bundle", "load_scene", "open_v4l2", "paper_split", "plan_stages", "read_manifest",
    "relative_error", "sha256_file", "shipped_bundles", "split_ids", "write_bundle",
]

if TYPE_CHECKING:  # for type checkers and IDEs; at run time these load lazily
    from .bundle.data_stats import DataStats
    from .bundle.force_calibration import ForceCalibration
    from .bundle.interval import ForceInterval, fit_interval
    from .data.dataset import AuthorsDataset, AuthorsDatasetWriter, Sample
    from .data.metrics import ErrorReport, ErrorStats, error_report, error_stats, relative_error
    from .depth import DepthOptions, DepthResult, DepthStage, MaxDeformationBaseline, NormalLUT
    from .gate.contact_gate import ContactGate, GateOptions, GateResult
    from .model.ladder import LadderChoice, choose_bundle
    from .model.onnx_model import OnnxForceModel
    from .outputs import CsvWriter, JsonlWriter, StdoutWriter
    from .runtime.depth_factory import plan_stages
    from .runtime.loop import ForceRuntime
    from .runtime.options import RuntimeOptions, RuntimeStats, Sensor
    from .scene import Scene, build_scene, default_bundle_path, describe_scene, load_scene, shipped_bundles
    from .sources.files import CameraSource, ReplayFolderSource, StreamLost, VideoFileSource, load_background, open_v4l2
    from .synthetic import (
        ContactSpec,
        DatasetOptions,
        DatasetSummary,
        IndenterSplit,
        SyntheticFrame,
        VirtualDigit,
        VirtualDigitOptions,
        VirtualDigitSource,
        generate_dataset,
        indenter_split,
        paper_split,
        split_ids,
    )
