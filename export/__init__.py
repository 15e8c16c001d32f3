"""tactile_force.export: trained checkpoints -> verified (quantized) ONNX bundles. Needs torch.

Options -> verb -> typed result:

    bundle = export_bundle("ckpt.pth", "rgbmod_fp32", ExportOptions(variant="rgbmod",
                           parity_data="dataset/"))
    q = quantize_bundle(bundle, "rgbmod_int8", QuantizeOptions(mode="int8-static"),
                        calibration="dataset/")
"""

from tactile_force.edge.errors import require as _require

_require("torch", "export", "tactile_force.export (checkpoint loading and ONNX export)")
_require("onnx", "export", "tactile_force.export (ONNX export and quantization)")

from .calibration import CalibrationData, CalibrationError, random_frames  # noqa: E402
from .checkpoint import Checkpoint, CheckpointError, load_checkpoint, load_into, model_from_checkpoint, save_checkpoint  # noqa: E402
from .graph import name_nodes, op_counts, ort_optimized_ops  # noqa: E402
from .macs import MacCount, count_macs  # noqa: E402
from .onnx_export import ExportOptions, ParityError, ParityResult, export_bundle, to_onnx  # noqa: E402
from .preprocess import ForceNet, Preprocess, fold_input_scaling, input_convs, network_hw, scale_factor  # noqa: E402
from .quantize import FrameCalibrationReader, QuantizeError, QuantizeOptions, quantize_bundle  # noqa: E402
from .zoo import (  # noqa: E402
                         VARIANT_INPUTS,
                         D,
                         Dmod,
                         ModelSpec,
                         RGBmod,
                         RGBmodD,
                         UnknownVariantError,
                         build_model,
                         check_variant,
                         fold_linear_head,
)

__all__ = [
    "CalibrationData", "CalibrationError", "Checkpoint", "CheckpointError", "D", "Dmod", "ExportOptions",
    "ForceNet", "FrameCalibrationReader", "MacCount", "ModelSpec", "ParityError", "ParityResult", "Preprocess",
    "QuantizeError", "QuantizeOptions", "RGBmod", "RGBmodD", "UnknownVariantError", "VARIANT_INPUTS", "build_model",
    "check_variant", "count_macs", "export_bundle", "fold_input_scaling", "fold_linear_head", "input_convs",
    "load_checkpoint", "load_into", "model_from_checkpoint", "name_nodes", "network_hw", "op_counts",
    "ort_optimized_ops", "quantize_bundle", "random_frames", "save_checkpoint", "scale_factor", "to_onnx",
]
