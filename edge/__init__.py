"""tactile_force.edge: the robot-side runtime (numpy + onnxruntime + OpenCV, never torch).

Data flow: frame source -> contact gate -> [depth stage for D/Dmod/RGBmod+D] -> ONNX
inference -> ForceReading. See design.md for the contracts.
"""

from .bundle import DEPTH_VARIANTS, VARIANTS, Bundle, Manifest, TensorSpec, load_bundle, sha256_file, write_bundle
from .dataset import AuthorsDataset, AuthorsDatasetWriter, Sample
from .errors import (AcceleratorUnavailableError, BundleError, DatasetError, FrameError, MissingExtraError, SceneError,
                     SourceError,
                     TactileForceError)
from .frames import FRAME_SHAPE, FrameSource, SourceStats, TimedFrame, check_frame
from .metrics import ErrorReport, ErrorStats, error_report, error_stats, relative_error
from .reading import MAX_VALID_FORCE_N, MIN_VALID_FORCE_N, Flags, ForceReading, StageLatency

# --- runtime (sources, gate, inference, scenes) ---
from .gate import ContactGate, GateOptions, GateResult
from .inference import LadderChoice, OnnxForceModel, choose_bundle
from .outputs import CsvWriter, JsonlWriter, StdoutWriter
from .runtime import ForceRuntime, RuntimeOptions, RuntimeStats, Sensor, plan_stages
from .scene import Scene, build_scene, default_bundle_path, describe_scene, load_scene
from .sources import CameraSource, ReplayFolderSource, StreamLost, VideoFileSource, load_background, open_v4l2
# --- synthetic ---
from .synthetic import (ContactSpec, DatasetOptions, DatasetSummary, IndenterSplit, SyntheticFrame, VirtualDigit,
                        VirtualDigitOptions, VirtualDigitSource, generate_dataset, indenter_split, paper_split,
                        split_ids)
# --- depth ---
from .depth import DepthOptions, DepthResult, DepthStage, MaxDeformationBaseline, NormalLUT

__all__ = [name for name in dir() if not name.startswith("_")]
