"""fp32 bundle -> int8 static (QDQ) / int8 dynamic / fp16 bundle, with an error report.

int8 static: activations uint8, weights int8 per channel (or per tensor), QDQ format, the
recommended format for ONNX Runtime on x86/ARM CPUs; ORT fuses each
DequantizeLinear -> Conv -> QuantizeLinear group into an integer QLinearConv at load time.
The final linear layer (and the reshape after it) stays float, so forces are not snapped
to an 8-bit grid, and so do the pooled features and their concatenation that feed it
(``float_head_inputs``; docs/benchmarks/int8_head.md); the graph's uint8 input and float32
``force_n`` output are unchanged.
The quantized model is compared with the fp32 one on real frames (and with ground truth
when the frames are labelled), using the paper's RE / MAE, and the figures go into the
manifest. Nothing is written unless every step succeeds.
"""

from __future__ import annotations

import contextlib
import copy
import dataclasses
import hashlib
import inspect
import io
import os
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from onnxruntime.quantization import CalibrationDataReader
from tactile_force.edge.bundle.manifest import (
    DiffFigures,
    ErrorFigures,
    ErrorReport,
    Precision,
    Quantization,
    SourceRef,
)
from tactile_force.edge.bundle.store import Bundle, load_bundle, write_bundle
from tactile_force.edge.data.metrics import error_stats
from tactile_force.edge.errors import TactileForceError, require
from tactile_force.edge.fitting.interval import fit_interval
from tactile_force.edge.report.progress import progress
from tactile_force.edge.typed_json import from_json

from .calibration import CalibrationData, CalibrationError
from .graph import name_nodes, op_counts, producer_chain
from .onnx_export import OUTPUT_NAME, ort_session, run_ort
from .zoo import VARIANT_INPUTS

MODES = ("int8-static", "int8-dynamic", "fp16")
METHODS = ("minmax", "entropy", "percentile")


class QuantizeError(TactileForceError, ValueError):
    """Quantization options or inputs are invalid; no bundle was written."""


@dataclass
class QuantizeOptions:
    """How to quantize.

    mode: 'int8-static' | 'int8-dynamic' | 'fp16'. method (int8-static): 'minmax' |
    'entropy' | 'percentile'. keep_float: extra node names to leave in float (the final
    linear layer always is). float_head_inputs: also keep the pooled features and their
    concatenation feeding the final linear layer in float (:func:`head_input_nodes`).
    histogram_bins: histogram size for entropy/percentile (entropy's
    threshold search time grows with it). min/max_calibration_frames bound the frames used.
    """

    mode: str = "int8-static"
    method: str = "minmax"
    per_channel: bool = True
    keep_float: list[str] = field(default_factory=list)
    percentile: float = 99.999
    histogram_bins: int = 2048
    min_calibration_frames: int = 10
    max_calibration_frames: int = 500
    name: str = ""
    overwrite: bool = False
    show_progress: bool = False
    float_head_inputs: bool = True
    #: int8-static / int8-dynamic weights in 7 bits (|q| <= 64: exact with onnxruntime's fused kernels on every
    #: CPU; 8 bits saturate on x86-64 without VNNI, edge/model/int8_host.py) or 8
    weight_bits: int = 7
    #: a no-contact frame of the sensor the calibration frames come from (HxWx3 uint8 BGR or
    #: an image path): with it, statistics of the calibration frames go into the manifest's
    #: ``data_stats`` and the runtime flags frames outside them ``out_of_distribution``
    background: object = None


#: Ops between the trunk's feature maps and the final linear layer: global pooling, reshapes
#: and the concatenation of the pooled features. Kept in float with ``float_head_inputs``.
HEAD_INPUT_OPS = ("ReduceMean", "GlobalAveragePool", "Flatten", "Reshape", "Squeeze", "Unsqueeze", "Concat")


def head_input_nodes(model, final_layer: str) -> list[str]:
    """Names of the nodes that make the final linear layer's input: the concatenation of the
    pooled features and the pooling itself (walking back from ``final_layer`` through
    :data:`HEAD_INPUT_OPS` only). Quantizing those vectors put most of the int8 error of
    full-resolution RGBmod into the force (0.193 N -> 0.043 N max difference when kept float)."""
    producers = {o: n for n in model.graph.node for o in n.output}
    node = next((n for n in model.graph.node if n.name == final_layer), None)
    if node is None:
        return []
    found: list[str] = []
    frontier = [node.input[0]]
    while frontier:
        n = producers.get(frontier.pop())
        if n is None or n.op_type not in HEAD_INPUT_OPS or n.name in found:
            continue
        found.append(n.name)
        frontier.extend(n.input)
    return found


def _ort_quant():
    import onnxruntime.quantization as q

    return q


class FrameCalibrationReader(CalibrationDataReader):
    """onnxruntime CalibrationDataReader over CalibrationData: one frame per feed, progress bar."""

    def __init__(self, data: CalibrationData, show_progress: bool = False) -> None:
        self.data = data
        self.show_progress = show_progress
        self.rewind()

    def get_next(self) -> dict[str, np.ndarray] | None:
        return next(self._it, None)

    def rewind(self) -> None:
        self._it = iter(progress(self.data.batches(1), total=len(self.data), desc="calibrating",
                                 enabled=self.show_progress))


def _check_options(o: QuantizeOptions) -> None:
    if o.mode not in MODES:
        raise QuantizeError(f"quantization mode {o.mode!r}; expected one of {', '.join(MODES)}")
    if o.method not in METHODS:
        raise QuantizeError(f"calibration method {o.method!r}; expected one of {', '.join(METHODS)}")
    if o.histogram_bins < 256:
        raise QuantizeError(f"histogram_bins {o.histogram_bins}; expected >= 256 (entropy searches 128 quantized bins)")
    if not (0 < o.percentile <= 100):
        raise QuantizeError(f"percentile {o.percentile}; expected 0 < p <= 100")


def _load_calibration(calibration, variant: str, o: QuantizeOptions, required: bool) -> CalibrationData | None:
    if calibration is None:
        if required:
            raise CalibrationError("int8-static quantization needs calibration frames (--calib FOLDER)")
        return None
    if isinstance(calibration, CalibrationData):
        data = calibration.subset(o.max_calibration_frames)
    else:
        data = CalibrationData.from_path(calibration, variant, limit=o.max_calibration_frames,
                                         show_progress=o.show_progress)
    if len(data) < o.min_calibration_frames:
        raise CalibrationError(f"{data.source}: only {len(data)} calibration frame(s); at least "
                               f"{o.min_calibration_frames} are needed "
                               "(a few hundred covering the force range is better)")
    missing = [n for n in _input_names(variant) if n not in data.inputs]
    if missing:
        raise CalibrationError(f"{data.source}: has no {', '.join(missing)} frames, which variant '{variant}' needs")
    return data


def _input_names(variant: str) -> tuple[str, ...]:
    return VARIANT_INPUTS[variant]


def _static(pre_path: Path, out_path: Path, data: CalibrationData, exclude: list[str], o: QuantizeOptions) -> dict:
    q = _ort_quant()
    method = {"minmax": q.CalibrationMethod.MinMax, "entropy": q.CalibrationMethod.Entropy,
              "percentile": q.CalibrationMethod.Percentile}[o.method]
    common = dict(quant_format=q.QuantFormat.QDQ, per_channel=o.per_channel, activation_type=q.QuantType.QUInt8,
                  weight_type=q.QuantType.QInt8, nodes_to_exclude=exclude, calibrate_method=method,
                  reduce_range=o.weight_bits == 7)
    # quantize_static cannot set the histogram size, and its Entropy default (128 bins searched
    # over 128 quantized bins) can never clip, i.e. it equals MinMax. So the ranges are computed
    # here with options.histogram_bins bins and handed over through ORT's calibration cache.
    by_method: dict[str, dict[str, int | float]] = {
        "entropy": {"num_bins": o.histogram_bins, "num_quantized_bins": 128},
        "percentile": {"num_bins": o.histogram_bins, "percentile": o.percentile}}
    hist = by_method.get(o.method, {})
    if hist and "calibration_cache_path" in inspect.signature(q.quantize_static).parameters:
        from onnxruntime.quantization.calibrate import create_calibrator, save_tensors_data

        aug = os.fspath(out_path.with_suffix(".aug.onnx"))
        calibrator = create_calibrator(pre_path, None, augmented_model_path=aug,
                                       calibrate_method=method, extra_options=hist)
        calibrator.collect_data(FrameCalibrationReader(data, o.show_progress))
        cache = out_path.with_suffix(".ranges.json")
        with contextlib.redirect_stdout(io.StringIO()):  # ORT prints histogram chatter
            save_tensors_data(calibrator.compute_data(), cache)
        q.quantize_static(os.fspath(pre_path), os.fspath(out_path), None, calibration_cache_path=os.fspath(cache),
                          **common)
    else:
        extra = {"CalibPercentile": o.percentile} if o.method == "percentile" else {}
        q.quantize_static(os.fspath(pre_path), os.fspath(out_path), FrameCalibrationReader(data, o.show_progress),
                          extra_options=extra, **common)
    info: dict[str, object] = {"format": "QDQ", "activations": "uint8 (asymmetric)",
                               "weights": "int8 (7-bit range)" if o.weight_bits == 7 else "int8",
            "per_channel": o.per_channel, "method": o.method, "calibration_data": data.source,
            "calibration_frames": len(data)}
    if o.method == "percentile":
        info["percentile"] = o.percentile
    if hist:
        info["histogram_bins"] = hist["num_bins"]
    return info


def _dynamic(pre_path: Path, out_path: Path, exclude: list[str], o: QuantizeOptions) -> dict:
    q = _ort_quant()
    # ORT's CPU ConvInteger kernel takes uint8 weights only. Only convolutions are quantized:
    # the dynamic quantizer renames the final Gemm (Gemm -> MatMul + Add), so excluding it by
    # name would not keep the force output float.
    q.quantize_dynamic(os.fspath(pre_path), os.fspath(out_path), per_channel=o.per_channel,
                       weight_type=q.QuantType.QUInt8, nodes_to_exclude=exclude, op_types_to_quantize=["Conv"])
    return {"format": "dynamic (ConvInteger / MatMulInteger)", "activations": "uint8, range computed per batch",
            "weights": "uint8", "per_channel": o.per_channel}


def _fp16(model, out_path: Path, exclude: list[str]) -> dict:
    onnx = require("onnx", "export", "fp16 conversion")
    from onnxruntime.transformers.float16 import convert_float_to_float16

    m16 = convert_float_to_float16(copy.deepcopy(model), keep_io_types=True, node_block_list=exclude)
    onnx.save(m16, os.fspath(out_path))
    return {"format": "float16 weights and activations", "io": "uint8 input, float32 output kept"}


def _error_report(fp32_bytes: bytes, q_bytes: bytes, data: CalibrationData, used_for_calibration: bool,
                  keep: list | None = None) -> ErrorReport:
    ref = run_ort(ort_session(fp32_bytes, threads=2), data)
    got = run_ort(ort_session(q_bytes, threads=2), data)
    if keep is not None:  # the quantized graph's estimates, for the interval (quantize_bundle)
        keep.append(got)
    if not np.all(np.isfinite(got)):
        raise QuantizeError("quantized model gives non-finite forces (NaN/inf); "
                            "try --method percentile or --keep-float")
    diff = np.abs(got - ref)
    # ErrorFigures has exactly the fields of edge.metrics.ErrorStats
    rep = ErrorReport(data=data.source, frames=len(data), same_frames_as_calibration=used_for_calibration,
                      vs_fp32=DiffFigures(**error_stats(got, ref).as_dict(), max_abs_diff_n=float(diff.max()),
                                          mean_abs_diff_n=float(diff.mean())))
    if data.forces is not None:
        rep.vs_truth = ErrorFigures(**error_stats(got, data.forces).as_dict())
        rep.fp32_vs_truth = ErrorFigures(**error_stats(ref, data.forces).as_dict())
    return rep


def quantize_bundle(src: Bundle | str | os.PathLike, dest: str | os.PathLike, options: QuantizeOptions | None = None,
                    calibration: CalibrationData | str | os.PathLike | None = None,
                    eval_data: CalibrationData | str | os.PathLike | None = None) -> Bundle:
    """Quantize an fp32 bundle into a new bundle at ``dest``.

    calibration: frames for int8-static (folder of PNGs, authors'-layout dataset or loaded
    CalibrationData); for the other modes it is optional and only used for the error report.
    eval_data: frames for the error report; defaults to the calibration frames.
    """
    o = options or QuantizeOptions()
    _check_options(o)
    onnx = require("onnx", "export", "Quantization")
    t0 = time.perf_counter()
    from tactile_force.edge.files.guard import OutputKind, check_output

    src_path = src.path if isinstance(src, Bundle) else src
    inputs = [(flag, p if isinstance(p, (str, os.PathLike)) else None)
              for flag, p in (("bundle", src_path), ("--calib", calibration), ("--eval", eval_data),
                              ("--background", o.background))]
    check_output(dest, inputs, force=o.overwrite, kind=OutputKind.BUNDLE)
    dest = Path(dest)
    bundle = src if isinstance(src, Bundle) else load_bundle(src)
    m = bundle.manifest
    if m.precision != "fp32":
        raise QuantizeError(f"{bundle.path}: is a {m.precision} bundle; quantize the fp32 bundle 'export' made")
    calib = _load_calibration(calibration, m.variant, o, required=o.mode == "int8-static")
    if eval_data is None:
        evaluation, same = calib, True
    elif isinstance(eval_data, CalibrationData):
        evaluation, same = eval_data, False
    else:
        evaluation, same = CalibrationData.from_path(eval_data, m.variant, limit=o.max_calibration_frames), False
    fp32_bytes = bundle.onnx_path.read_bytes()
    with tempfile.TemporaryDirectory(prefix="tactile-force-quant-") as tmp_name:
        tmp = Path(tmp_name)
        raw, pre, out = tmp / "fp32.onnx", tmp / "pre.onnx", tmp / "quant.onnx"
        raw.write_bytes(fp32_bytes)
        if o.mode == "fp16":
            model = onnx.load(os.fspath(raw))
        else:
            _ort_quant().quant_pre_process(os.fspath(raw), os.fspath(pre), skip_symbolic_shape=True)
            model = onnx.load(os.fspath(pre))
        name_nodes(model)  # before choosing exclusions: an empty name would exclude every node
        # value_info naming initializers goes stale when the dynamic quantizer transposes Gemm weights
        inits = {i.name for i in model.graph.initializer}
        keep = [vi for vi in model.graph.value_info if vi.name not in inits]
        del model.graph.value_info[:]
        model.graph.value_info.extend(keep)
        onnx.save(model, os.fspath(pre))
        names = {n.name for n in model.graph.node}
        unknown = [n for n in o.keep_float if n not in names]
        if unknown:
            sample = ", ".join(sorted(n.name for n in model.graph.node if n.op_type == "Conv")[:6])
            raise QuantizeError(f"--keep-float: no node named {', '.join(unknown)} in {bundle.onnx_path.name} "
                                f"(e.g. {sample}; list them with 'tactile-force bundle show --nodes')")
        final = producer_chain(model, OUTPUT_NAME)
        head = head_input_nodes(model, final[-1]) if o.float_head_inputs else []
        exclude = list(dict.fromkeys(final + head + list(o.keep_float)))
        if o.mode == "int8-static":
            # the graph reads frames reduced as the runtime reduces them (manifest inputs[].reduction)
            info = _static(pre, out, calib.for_manifest(m), exclude, o)  # type: ignore[union-attr]
        elif o.mode == "int8-dynamic":
            info = _dynamic(pre, out, exclude, o)
        else:
            info = _fp16(model, out, exclude)
        q_bytes = out.read_bytes()
    q_model = onnx.load_from_string(q_bytes)
    out_type = q_model.graph.output[0].type.tensor_type.elem_type
    if q_model.graph.output[0].name != OUTPUT_NAME or out_type != onnx.TensorProto.FLOAT:
        raise QuantizeError(f"quantized graph's output is not float32 '{OUTPUT_NAME}'; refusing to write it")
    info.update({"kept_float": exclude, "final_layer": final[-1], "tool": "onnxruntime.quantization",
                 "op_counts": dict(sorted(op_counts(q_model).items()))})
    manifest = copy.deepcopy(m)
    manifest.precision = Precision(o.mode)
    manifest.name = o.name or dest.name
    # The runtime's honesty checks need data_stats: from the calibration frames (contact sizes
    # too with --background, below); without new frames the source's are kept; with neither, say so.
    rgb_calib = calib is not None and "rgb" in calib.inputs
    manifest.data_stats_missing = ""
    if rgb_calib and o.background is None and m.data_stats is None:
        manifest.data_stats = calibration_data_stats(calib, None)  # type: ignore[arg-type]
    elif not rgb_calib and m.data_stats is None:
        from tactile_force.edge.fitting.data_stats import no_frames_warning

        manifest.data_stats_missing = no_frames_warning(
            "quantize", "RGB calibration frames (and the source bundle has no data_stats)")
    manifest.quantization = from_json(Quantization, info, "quantization")
    estimates: list = []
    manifest.error = (_error_report(fp32_bytes, q_bytes, evaluation.for_manifest(m), same, estimates)
                      if evaluation is not None else None)
    # Every reading's error bar (edge/bundle/interval.py): split conformal on the labelled frames the
    # error is scored on; without labels none (the source's interval described another graph).
    manifest.interval = None
    if evaluation is not None and evaluation.forces is not None:
        manifest.interval = fit_interval(estimates[0], evaluation.forces,
                                         model_sha256=hashlib.sha256(q_bytes).hexdigest(),
                                         data=f"{evaluation.source} ({len(evaluation)} labelled frames"
                                              + (", also the int8 calibration frames)" if same else ")"))
    manifest.provenance = dataclasses.replace(m.provenance, quantized_from=SourceRef(bundle=m.name, sha256=m.sha256),
                                              quantize_seconds=round(time.perf_counter() - t0, 2))
    if o.background is not None and calib is not None and "rgb" in calib.inputs:
        manifest.data_stats = calibration_data_stats(calib, o.background)
    return write_bundle(dest, q_bytes, manifest, overwrite=o.overwrite, inputs=inputs)


def calibration_data_stats(data: CalibrationData, background: object):
    """Manifest ``data_stats`` of calibration frames seen against a no-contact ``background``
    (None: their colours only, with a warning that the contact-size check is off)."""
    from tactile_force.edge.fitting.data_stats import compute_data_stats, frames_data_stats
    from tactile_force.edge.frames import check_frame

    if background is None:
        return frames_data_stats(list(data.inputs["rgb"]), None, data.source, "quantize")
    if isinstance(background, (str, os.PathLike)):
        import cv2

        img = cv2.imread(os.fspath(background), cv2.IMREAD_COLOR)
        if img is None:
            raise QuantizeError(f"background {background}: not a readable image; expected a no-contact frame "
                                "(320x240 BGR PNG) of the sensor the calibration frames come from")
        background = img
    bg = check_frame(background, "background")
    return compute_data_stats(list(data.inputs["rgb"]), bg, source=data.source)
