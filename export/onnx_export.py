"""Checkpoint + variant -> verified fp32 ONNX bundle (preprocessing inside the graph).

The graph takes uint8 NHWC images at the network resolution with a dynamic batch (``rgb``:
N x 320/k x 240/k x 3 BGR, ``depth``: N x 320/k x 240/k x 1; k = 1 / input_scale; full
frames for k = 1) and returns ``force_n`` (N,) float32 in newtons. A compact model's frames
are reduced outside the graph, once per frame, by the runtime (edge/gate/reduce.py; the manifest
records the reduction in ``inputs[].reduction``), exactly as the training reduced them.
The purely linear head is folded into one Gemm, and (by default) the BGR flip and the 1/255
into conv1's weights, leaving Transpose (uint8) -> Cast in front of conv1.
Before anything is written, ONNX Runtime is compared with torch eager of the unfolded
ForceNet (the training form) on real frames; a difference above
``parity_tol_n`` aborts and leaves no bundle.
"""

from __future__ import annotations

import hashlib
import logging
import os
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tactile_force.edge.bundle.manifest import (
    Architecture,
    FrameReduction,
    InputKind,
    InputSpec,
    Manifest,
    ModelOutputSpec,
    Parity,
    Precision,
    Provenance,
    Variant,
)
from tactile_force.edge.bundle.store import Bundle, write_bundle
from tactile_force.edge.errors import CheckFailedError, TactileForceError
from tactile_force.edge.fitting.interval import fit_interval
from torch import nn

from .calibration import CalibrationData, random_frames
from .checkpoint import model_from_checkpoint
from .graph import name_nodes
from .macs import count_macs
from .preprocess import ForceNet, default_reduction, network_hw, scale_factor
from .zoo import RESNET18_BLOCKS, VARIANT_INPUTS, ModelSpec, check_variant

OUTPUT_NAME = "force_n"


class ParityError(CheckFailedError):  # a failed check: the CLI exits 1
    """ONNX Runtime and torch disagree by more than the tolerance; no bundle was written."""


@dataclass
class ExportOptions:
    """How to export. variant/width/input_scale default to the checkpoint's metadata.

    parity_data: an authors'-layout dataset or PNG folder (or loaded CalibrationData);
    None checks on random frames and says so in the manifest. fold_preprocess: fold the BGR
    flip and the 1/255 into conv1's weights (exact up to float rounding, faster graph).
    background: a no-contact frame (or image path) of the parity frames' sensor: the manifest's
    ``data_stats`` (from the parity frames) then also record contact sizes. Without parity
    frames the bundle has no data_stats and ``data_stats_missing`` says the checks are off.
    """

    variant: str | None = None
    width: float | None = None
    input_scale: float | None = None
    parity_data: str | os.PathLike | CalibrationData | None = None
    parity_tol_n: float = 1e-4
    max_parity_frames: int = 32
    opset: int = 18
    fold_head: bool = True
    fold_preprocess: bool = True
    name: str = ""
    overwrite: bool = False
    trained_on: str = ""
    background: str | os.PathLike | np.ndarray | None = None


@dataclass
class ParityResult:
    """ORT vs torch eager on the same frames (N)."""

    max_abs_diff_n: float
    mean_abs_diff_n: float
    frames: int
    source: str
    tolerance_n: float
    #: ONNX Runtime's forces on the parity frames (N,), for the interval when they are labelled
    estimates: np.ndarray | None = field(default=None, repr=False)

    def as_dict(self) -> dict:
        return {"max_abs_diff_n": self.max_abs_diff_n, "mean_abs_diff_n": self.mean_abs_diff_n,
                "frames": self.frames, "data": self.source, "tolerance_n": self.tolerance_n,
                "reference": "torch eager, unfolded head", "runtime": "onnxruntime CPUExecutionProvider"}


class _Single(nn.Module):
    def __init__(self, net: ForceNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class _Pair(nn.Module):
    def __init__(self, net: ForceNet) -> None:
        super().__init__()
        self.net = net

    def forward(self, rgb: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
        return self.net(rgb, depth)


def written_opset(onnx_bytes: bytes) -> int:
    """The default-domain opset a serialized ONNX model really declares."""
    import onnx

    model = onnx.load_from_string(onnx_bytes)
    return next((int(o.version) for o in model.opset_import if o.domain in ("", "ai.onnx")), 0)


def to_onnx(net: ForceNet, opset: int = 18) -> bytes:
    """Export a ForceNet to ONNX bytes: uint8 NHWC inputs, dynamic batch, output 'force_n' (N,)."""
    if opset < 17:
        raise TactileForceError(f"opset {opset}: need >= 17")
    names = list(net.input_names)
    wrapper = (_Single if len(names) == 1 else _Pair)(net).eval()
    rows, cols = network_hw(net.spec.input_scale) if net.network_input else (320, 240)
    args = tuple(torch.zeros((2, rows, cols, 3 if n == "rgb" else 1), dtype=torch.uint8) for n in names)
    batch = torch.export.Dim("batch", min=1, max=4096)
    dyn = tuple({0: batch} for _ in names)
    with warnings.catch_warnings(), torch.no_grad():
        warnings.simplefilter("ignore")
        level = logging.getLogger("torch.onnx").level
        logging.getLogger("torch.onnx").setLevel(logging.ERROR)
        try:
            prog = torch.onnx.export(wrapper, args, dynamo=True, input_names=names, output_names=[OUTPUT_NAME],
                                     dynamic_shapes=dyn, opset_version=opset, verbose=False, optimize=True)
        finally:
            logging.getLogger("torch.onnx").setLevel(level)
    if prog is None:
        raise TactileForceError("torch.onnx.export returned no program; cannot export this model")
    model = prog.model_proto
    name_nodes(model)
    del model.metadata_props[:]
    model.producer_name = "tactile-force"
    return model.SerializeToString()


def ort_session(model_bytes: bytes, threads: int = 1):
    """A CPU onnxruntime session on model bytes."""
    import onnxruntime as ort
    from tactile_force.edge.model.onnx_model import session_options

    return ort.InferenceSession(model_bytes, session_options(threads), providers=["CPUExecutionProvider"])


def run_ort(session, data: CalibrationData, batch_size: int = 4) -> np.ndarray:
    """Forces (N,) float64 from an ORT session over ``data`` in batches."""
    return np.concatenate([np.asarray(session.run([OUTPUT_NAME], feed)[0], dtype=np.float64).reshape(-1)
                           for feed in data.batches(batch_size)])


@torch.no_grad()
def run_torch(net: ForceNet, data: CalibrationData, batch_size: int = 4) -> np.ndarray:
    """Forces (N,) float64 from torch eager over ``data`` in batches."""
    out = []
    for feed in data.batches(batch_size):
        out.append(net(*(torch.from_numpy(np.ascontiguousarray(feed[n])) for n in net.input_names)).double().numpy())
    return np.concatenate(out).reshape(-1)


def check_parity(net: ForceNet, model_bytes: bytes, data: CalibrationData, tol_n: float,
                 reduction: FrameReduction | None = None) -> ParityResult:
    """Compare ORT with torch eager (full-resolution frames); ParityError if max |diff| > tol_n or
    outputs are not finite. ``reduction``: the graph starts at the network resolution and is fed
    the frames reduced as the runtime reduces them."""
    ref = run_torch(net, data)
    fed = data.reduced(reduction) if reduction is not None else data
    got = run_ort(ort_session(model_bytes, threads=max(1, min(4, os.cpu_count() or 1))), fed, batch_size=3)
    if not (np.all(np.isfinite(ref)) and np.all(np.isfinite(got))):
        raise ParityError("parity check: non-finite force (NaN/inf) from torch or ONNX Runtime; "
                          "the checkpoint's weights are probably corrupted")
    diff = np.abs(got - ref)
    res = ParityResult(float(diff.max()), float(diff.mean()), len(data), data.source, tol_n, got)
    if res.max_abs_diff_n > tol_n:
        raise ParityError(f"parity check failed: ONNX Runtime differs from torch by up to {res.max_abs_diff_n:.3g} N "
                          f"on {res.frames} frames ({data.source}); tolerance {tol_n:g} N. No bundle written.")
    return res


def _input_specs(variant: str, input_scale: float = 1.0) -> list[InputSpec]:
    """The network input records: the frame reduced by 1/input_scale (edge/gate/reduce.py's
    default reduction; ``none`` at full resolution)."""
    specs = []
    k = scale_factor(input_scale)
    rows, cols = network_hw(input_scale)
    for n in VARIANT_INPUTS[variant]:
        rgb = n == "rgb"
        specs.append(InputSpec(name=n, kind=InputKind(n), shape=[-1, rows, cols, 3 if rgb else 1],
                               colour_order="BGR" if rgb else "GRAY", reduction=default_reduction(k)))
    return specs


def output_spec() -> ModelOutputSpec:
    return ModelOutputSpec(name=OUTPUT_NAME)


def preprocessing_steps(spec: ModelSpec, folded: bool = False) -> list[str]:
    """What the graph does to the raw frames before the network, in order."""
    k = scale_factor(spec.input_scale)
    outside = []
    if k > 1:
        r, c = network_hw(spec.input_scale)
        red = default_reduction(k)
        outside.append(f"frame 320x240 -> {r}x{c} outside the graph, once per frame: {red.method.value} x{k} "
                       "(edge/gate/reduce.py)")
    if folded:
        steps = [*outside, "NHWC -> NCHW (uint8)", "cast uint8 -> float32"]
        if "rgb" in VARIANT_INPUTS[spec.variant]:
            steps.append("BGR -> RGB (rgb input): folded into conv1's weights")
        steps.append("divide by 255: folded into conv1's weights")
        return steps
    steps = [*outside, "cast uint8 -> float32", "NHWC -> NCHW"]
    if "rgb" in VARIANT_INPUTS[spec.variant]:
        steps.append("BGR -> RGB (rgb input)")
    steps.append("divide by 255")
    return steps


def _resolve(source, options: ExportOptions) -> tuple[nn.Module, ModelSpec, dict]:
    if isinstance(source, ForceNet):
        return source.model, source.spec, {"checkpoint": "in-memory ForceNet"}
    if isinstance(source, nn.Module):
        if not options.variant:
            raise TactileForceError("export of an in-memory model needs ExportOptions.variant")
        spec = ModelSpec(check_variant(options.variant), float(options.width or 1.0), float(options.input_scale or 1.0),
                         getattr(source, "blocks", RESNET18_BLOCKS))
        return source.eval(), spec, {"checkpoint": "in-memory module"}
    path = Path(source)
    model, spec, ckpt = model_from_checkpoint(path, options.variant, options.width, options.input_scale)
    prov = {"checkpoint": path.name, "checkpoint_sha256": hashlib.sha256(path.read_bytes()).hexdigest(),
            "checkpoint_format": "tactile-force" if ckpt.meta else "authors' (state_dict only)"}
    for key in ("trained_on", "note", "epochs"):
        if key in ckpt.meta:
            prov[key] = ckpt.meta[key]
    return model, spec, prov


def _data_stats_fields(data: CalibrationData | None, background: object) -> dict:
    """Manifest ``data_stats`` of the parity frames the export saw (RGB variants), else
    ``data_stats_missing``: why there are none (the runtime's honesty checks are off)."""
    from tactile_force.edge.fitting.data_stats import frames_data_stats, no_frames_warning

    if data is not None and "rgb" in data.inputs and len(data.inputs["rgb"]):
        return {"data_stats": frames_data_stats(list(data.inputs["rgb"]), background, data.source, "export")}
    if data is not None:
        return {"data_stats_missing": no_frames_warning("export", "RGB frames (a depth-only variant)")}
    return {"data_stats_missing": no_frames_warning("export", "real frames (no --parity-data; parity was checked "
                                                    "on random frames)")}


def export_bundle(source: str | os.PathLike | nn.Module, dest: str | os.PathLike,
                  options: ExportOptions | None = None) -> Bundle:
    """Export a checkpoint file (or in-memory model / ForceNet) to a verified fp32 bundle at ``dest``."""
    options = options or ExportOptions()
    t0 = time.perf_counter()
    from tactile_force.edge.files.guard import OutputKind, check_output

    inputs = [("checkpoint", source if isinstance(source, (str, os.PathLike)) else None),
              ("--parity-data", options.parity_data if isinstance(options.parity_data, (str, os.PathLike)) else None)]
    check_output(dest, inputs, force=options.overwrite, kind=OutputKind.BUNDLE)
    dest = Path(dest)
    model, spec, prov = _resolve(source, options)
    scale_factor(spec.input_scale)
    model.eval()
    if isinstance(options.parity_data, CalibrationData):
        data = options.parity_data
    elif options.parity_data is not None:
        data = CalibrationData.from_path(options.parity_data, spec.variant, limit=options.max_parity_frames)
    else:
        data = random_frames(spec.variant)
    eager = ForceNet(model, spec, folded=False).eval()
    k = scale_factor(spec.input_scale)
    graph_net = ForceNet(model, spec, folded=options.fold_head, fold_preprocess=options.fold_preprocess,
                         network_input=k > 1).eval()
    onnx_bytes = to_onnx(graph_net, options.opset)
    parity = check_parity(eager, onnx_bytes, data, options.parity_tol_n, default_reduction(k) if k > 1 else None)
    import onnx

    macs = count_macs(onnx.load_from_string(onnx_bytes))
    r, c = network_hw(spec.input_scale)
    known = {k: ckpt_v for k, ckpt_v in prov.items() if k in ("checkpoint", "checkpoint_sha256", "checkpoint_format",
                                                             "note")}
    epochs = prov.get("epochs")
    manifest = Manifest(
        variant=Variant(spec.variant), precision=Precision.FP32, inputs=_input_specs(spec.variant, spec.input_scale),
        output=output_spec(), name=options.name or dest.name,
        preprocessing=preprocessing_steps(spec, options.fold_preprocess),
        architecture=Architecture(family="resnet18", width=spec.width, input_scale=spec.input_scale,
                                  network_input_hw=[r, c], head_folded=options.fold_head,
                                  preprocess_folded=options.fold_preprocess, gmacs=round(macs.gmacs, 4),
                                  macs_by_op=dict(macs.by_op), params=int(sum(p.numel() for p in model.parameters())),
                                  opset=written_opset(onnx_bytes), blocks=list(spec.blocks)),
        parity=Parity(max_abs_diff_n=parity.max_abs_diff_n, mean_abs_diff_n=parity.mean_abs_diff_n,
                      frames=parity.frames, data=parity.source, tolerance_n=parity.tolerance_n),
        **_data_stats_fields(data if options.parity_data is not None else None, options.background),
        provenance=Provenance(**{k: str(v) for k, v in known.items()},
                              epochs=epochs if isinstance(epochs, int) and not isinstance(epochs, bool) else None,
                              trained_on=str(options.trained_on or prov.get("trained_on", "unknown")),
                              torch=torch.__version__, exporter="torch.onnx.export (dynamo)",
                              export_seconds=round(time.perf_counter() - t0, 2)),
    )
    if data.forces is not None and parity.estimates is not None:
        # labelled parity frames: every reading's error bar, split conformal (edge/bundle/interval.py); they
        # must be frames the checkpoint never trained on for the stated coverage to hold
        manifest.interval = fit_interval(parity.estimates, data.forces, model_sha256=hashlib.sha256(onnx_bytes)
                                         .hexdigest(), data=f"{data.source} ({len(data)} labelled parity frames)")
    return write_bundle(dest, onnx_bytes, manifest, overwrite=options.overwrite, inputs=inputs)
