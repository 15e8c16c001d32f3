"""Raw uint8 frames -> network input, as one torch module used by training AND export.

The exported ONNX graph contains this module, so edge/ feeds raw frames and the network sees
what it saw in training:

    rgb   (N, 320, 240, 3) uint8 BGR  -> (N, 3, 320/k, 240/k) float32 RGB in [0, 1]
    depth (N, 320, 240, 1) uint8      -> (N, 1, 320/k, 240/k) float32 in [0, 1]

Steps: for ``input_scale = 1/k`` the frame's reduction to the network resolution, exactly the
runtime's (:func:`tactile_force.edge.gate.reduce.default_reduction`: successive 2 x 2 box averages
each rounded half up for a power-of-two k, else a k x k box average rounded half to even;
the result is the same uint8 image edge/gate/reduce.py makes), then NHWC -> NCHW, cast to float,
BGR -> RGB (rgb only), / 255.

Exported graphs of compact models start at the network resolution (``network_input=True``):
the reduction is not in the graph; the runtime reduces each frame once (the contact gate
judges the same image) and the manifest records how (``inputs[].reduction``).

At export, ``fold_preprocess=True`` leaves the graph only NHWC -> NCHW (on uint8) and the
cast, and moves the BGR flip and the 1/255 into a copy of each input's first convolution
(:func:`fold_input_scaling`). Both are per-channel linear maps and conv1 pads with zeros, so
the network computes the same function up to float rounding. Training keeps the unfolded form.
"""

from __future__ import annotations

import copy

import torch
from tactile_force.edge.bundle.manifest import FrameReduction, Reduction
from tactile_force.edge.errors import TactileForceError
from tactile_force.edge.frames import FRAME_SHAPE
from tactile_force.edge.gate.reduce import default_reduction
from torch import nn

from .zoo import INPUT_CHANNELS, VARIANT_INPUTS, ModelSpec, RGBmodD, check_variant, fold_linear_head


def scale_factor(input_scale: float) -> int:
    """k for ``input_scale = 1/k``; the frame's 320 x 240 must be divisible by k."""
    s = float(input_scale)
    k = round(1.0 / s) if s > 0 else 0
    if k < 1 or abs(1.0 / k - s) > 1e-6 or FRAME_SHAPE[0] % k or FRAME_SHAPE[1] % k:
        raise TactileForceError(
            f"input_scale {input_scale!r} not supported; expected 1/k with k dividing 320 and 240 "
            "(1, 1/2, 1/4, 1/5, 1/8, 1/10, ...)")
    return k


def network_hw(input_scale: float) -> tuple[int, int]:
    """(rows, cols) the network sees for a 320 x 240 frame at ``input_scale``."""
    k = scale_factor(input_scale)
    return FRAME_SHAPE[0] // k, FRAME_SHAPE[1] // k


def reduce_nchw(x: torch.Tensor, reduction: FrameReduction) -> torch.Tensor:
    """The runtime's frame reduction (edge/gate/reduce.py) on a float NCHW batch of uint8 values,
    bit for bit: ``area-2x-steps``: floor(2x2 mean + 1/2) per step; ``area``: the k x k mean
    rounded half to even (torch.round). Exact in float32 (sums of at most 64 x 255)."""
    k = reduction.factor
    if reduction.method is Reduction.NONE:
        return x
    if reduction.method is Reduction.AREA_2X_STEPS:
        while k > 1:
            x = torch.floor(nn.functional.avg_pool2d(x, 2) + 0.5)
            k //= 2
        return x
    return torch.round(nn.functional.avg_pool2d(x, k))


class Preprocess(nn.Module):
    """uint8 NHWC frame batch -> float NCHW network input (see module docstring).

    ``folded=True``: NHWC -> NCHW on uint8 and cast only; the output stays BGR in 0..255, for
    a conv1 whose weights hold the flip and the 1/255. ``network_input=True`` (export): the
    input is already reduced to the network resolution (the graph starts there); otherwise a
    full-resolution frame is reduced here exactly as the runtime reduces it.
    """

    def __init__(self, input_scale: float = 1.0, kind: str = "rgb", folded: bool = False,
                 network_input: bool = False) -> None:
        super().__init__()
        if kind not in INPUT_CHANNELS:
            raise TactileForceError(f"input kind {kind!r}; expected 'rgb' or 'depth'")
        self.kind = kind
        self.folded = folded
        self.k = scale_factor(input_scale)
        self.reduction = default_reduction(self.k)
        self.network_input = network_input

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = x.permute(0, 3, 1, 2).float()  # exports as Transpose on uint8, then Cast
        if not self.network_input:
            x = reduce_nchw(x, self.reduction)
        if self.folded:
            return x
        if self.kind == "rgb":
            x = x.flip(1)  # BGR -> RGB
        return x / 255.0


def input_convs(model: nn.Module) -> dict[str, nn.Conv2d]:
    """The first convolution each network input ('rgb' / 'depth') goes through."""
    if isinstance(model, RGBmodD):
        return {"rgb": model.model_rgb.conv1, "depth": model.model_mask.conv1}
    conv = getattr(model, "conv1", None)
    if not isinstance(conv, nn.Conv2d):
        raise TactileForceError(f"{type(model).__name__}: has no first convolution 'conv1' to fold the input "
                                "scaling into; export it with fold_preprocess=False")
    return {"rgb" if conv.in_channels == 3 else "depth": conv}


def fold_input_scaling(model: nn.Module, variant: str) -> nn.Module:
    """A copy of ``model`` whose conv1 weights take raw frames: input channels reversed
    (BGR -> RGB, rgb input only) and divided by 255 (computed in float64).

    ``fold_input_scaling(m, v)(pool(x))`` equals ``m(pool(x)[:, ::-1] / 255)`` for rgb (and
    ``m(pool(x) / 255)`` for depth) up to float rounding; the original model is not changed.
    """
    names = VARIANT_INPUTS[check_variant(variant)]
    folded = copy.deepcopy(model)  # keeps shared modules shared (RGBmod+D's depth trunk)
    convs = input_convs(folded)
    if set(convs) != set(names):
        raise TactileForceError(f"{type(model).__name__}: first convolutions take {sorted(convs)} inputs but variant "
                                f"{variant!r} has inputs {list(names)}")
    with torch.no_grad():
        for name, conv in convs.items():
            if conv.in_channels != INPUT_CHANNELS[name] or conv.padding_mode != "zeros":
                raise TactileForceError(f"{name} conv1: {conv.in_channels} input channels, padding "
                                        f"{conv.padding_mode!r}; expected {INPUT_CHANNELS[name]} and 'zeros'")
            w = conv.weight.double()
            if name == "rgb":
                w = w.flip(1)  # conv1 reads BGR channels in the order RGB weights expect
            conv.weight.copy_((w / 255.0).to(conv.weight.dtype))
    return folded


class ForceNet(nn.Module):
    """Preprocess + model: raw uint8 NHWC batches in, force in N out, shape (N,).

    ``forward(rgb)`` for rgbmod, ``forward(depth)`` for d/dmod, ``forward(rgb, depth)``
    for rgbmod+d. Training calls this with uint8 batches, so the preprocessing it learns
    with is the one the exported graph runs. ``folded=True`` evaluates the head as the
    single folded linear map (what the ONNX graph holds). ``fold_preprocess=True`` (export
    only) runs a copy of ``model`` with the BGR flip and 1/255 folded into conv1 (see
    :func:`fold_input_scaling`); ``model`` itself is left as it is. ``network_input=True``
    (export of a compact model): the inputs are frames already reduced to the network
    resolution (:func:`tactile_force.edge.gate.reduce.default_reduction`), as the runtime feeds them.
    """

    def __init__(self, model: nn.Module, spec: ModelSpec, folded: bool = False, fold_preprocess: bool = False,
                 network_input: bool = False) -> None:
        super().__init__()
        self.spec = ModelSpec(check_variant(spec.variant), float(spec.width), float(spec.input_scale), spec.blocks)
        self.model = fold_input_scaling(model, self.spec.variant) if fold_preprocess else model
        self.input_names = VARIANT_INPUTS[self.spec.variant]
        self.fold_preprocess = fold_preprocess
        self.network_input = network_input
        self.pre = nn.ModuleDict({n: Preprocess(spec.input_scale, n, fold_preprocess, network_input)
                                  for n in self.input_names})
        self.folded = folded
        if folded:
            w, b = fold_linear_head(self.model)
            self.head = nn.Linear(w.shape[1], 1)
            with torch.no_grad():
                self.head.weight.copy_(w)
                self.head.bias.copy_(b)

    def forward(self, *frames: torch.Tensor) -> torch.Tensor:
        if len(frames) != len(self.input_names):
            raise TactileForceError(f"{self.spec.variant} takes inputs {self.input_names}, got {len(frames)} tensors")
        xs = [self.pre[n](f) for n, f in zip(self.input_names, frames)]
        if self.folded:
            features = self.model.features(*xs)  # type: ignore[operator]  # ResNet-18 variants in zoo.py
            return self.head(torch.cat(features, dim=1)).reshape(-1)
        return self.model(*xs).reshape(-1)
