"""tactile_force.edge: the robot-side runtime (numpy + onnxruntime + OpenCV; numba and SciPy
only with the ``fast`` and ``paper`` extras; never torch).

Data flow: frame source -> contact gate -> [depth stage for D/Dmod/RGBmod+D] -> ONNX
inference -> ForceReading. See docs/architecture.md; the subpackages are named for their
job: ``sources``, ``gate``, ``depth``, ``model``, ``runtime``, ``outputs``, ``scene``,
``bundle``, ``fitting``, ``data``, ``synthetic``, ``cli``.

Importing this package loads the contracts (frames, readings, the bundle and its manifest,
errors) and nothing else; every other name below is imported on first use, so an RGBmod
runtime never loads the depth stage, the virtual DIGIT or a device library.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

# _cli_start first of the package: a Ctrl-C while the CLI starts exits 130, no traceback
from . import _cli_start, _moved  # noqa: F401
from .bundle.manifest import InputKind, Manifest, Precision, Variant
from .bundle.store import Bundle, load_bundle, read_manifest, write_bundle
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
    # sources, gate, model, runtime, writers
    "CameraSource": "sources", "ReplayFolderSource": "sources", "VideoFileSource": "sources",
    "StreamLost": "sources", "load_background": "sources", "VirtualDigitSource": "synthetic",
    "ContactGate": "gate", "GateOptions": "gate", "GateResult": "gate",
    "OnnxForceModel": "model", "LadderChoice": "model.ladder", "choose_bundle": "model.ladder",
    "ForceRuntime": "runtime", "RuntimeOptions": "runtime", "RuntimeStats": "runtime", "Sensor": "runtime",
    "CsvWriter": "outputs", "JsonlWriter": "outputs", "StdoutWriter": "outputs",
    # scenes and the shipped bundles
    "Scene": "scene", "build_scene": "scene", "default_bundle_path": "scene", "describe_scene": "scene",
    "load_scene": "scene", "shipped_bundles": "scene",
    # a bundle's records, labelled data
    "ForceCalibration": "bundle.force_calibration", "DataStats": "bundle.data_stats",
    "ForceInterval": "bundle.interval", "AuthorsDataset": "data.dataset",
}

def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:  # a name earlier versions exported here: its new home, with a DeprecationWarning
        return _moved.old_name(__name__, name)
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


__all__ = [
    # contracts
    "FRAME_SHAPE", "FrameSource", "SourceStats", "TimedFrame", "check_frame",
    "MAX_VALID_FORCE_N", "MIN_VALID_FORCE_N", "Flags", "ForceReading", "IntervalState", "StageLatency",
    # errors
    "AcceleratorUnavailableError", "ArgumentTypeError", "BundleError", "DatasetError", "FrameError",
    "MissingExtraError", "OptionsError", "SceneError", "SourceError", "TactileForceError",
    # the bundle and its records
    "Bundle", "InputKind", "Manifest", "Precision", "Variant", "load_bundle", "read_manifest", "write_bundle",
    "DataStats", "ForceCalibration", "ForceInterval",
    # sources, gate, model, runtime, writers
    "CameraSource", "ReplayFolderSource", "StreamLost", "VideoFileSource", "VirtualDigitSource", "load_background",
    "ContactGate", "GateOptions", "GateResult",
    "LadderChoice", "OnnxForceModel", "choose_bundle",
    "ForceRuntime", "RuntimeOptions", "RuntimeStats", "Sensor",
    "CsvWriter", "JsonlWriter", "StdoutWriter",
    # scenes, shipped bundles, labelled data
    "Scene", "build_scene", "default_bundle_path", "describe_scene", "load_scene", "shipped_bundles",
    "AuthorsDataset",
]

if TYPE_CHECKING:  # for type checkers and IDEs; at run time these load lazily
    from .bundle.data_stats import DataStats
    from .bundle.force_calibration import ForceCalibration
    from .bundle.interval import ForceInterval
    from .data.dataset import AuthorsDataset
    from .gate import ContactGate, GateOptions, GateResult
    from .model import OnnxForceModel
    from .model.ladder import LadderChoice, choose_bundle
    from .outputs import CsvWriter, JsonlWriter, StdoutWriter
    from .runtime import ForceRuntime, RuntimeOptions, RuntimeStats, Sensor
    from .scene import Scene, build_scene, default_bundle_path, describe_scene, load_scene, shipped_bundles
    from .sources import CameraSource, ReplayFolderSource, StreamLost, VideoFileSource, load_background
    from .synthetic import VirtualDigitSource
