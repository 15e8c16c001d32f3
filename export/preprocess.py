"""Raw uint8 frames -> network input, as one torch module used by training AND export.

The exported ONNX graph contains exactly this module, so edge/ feeds raw frames and the
network sees what it saw in training:

    rgb   (N, 320, 240, 3) uint8 BGR  -> (N, 3, 320/k, 240/k) float32 RGB in [0, 1]
    depth (N, 320, 240, 1) uint8      -> (N, 1, 320/k, 240/k) float32 in [0, 1]

Steps: cast to float, NHWC -> NCHW, BGR -> RGB (rgb only), / 255, and for
``input_scale = 1/k`` an exact k x k area average (AveragePool, stride k).
"""

from __future__ import annotations

import torch
from torch import nn

from tactile_force.edge.errors import TactileForceError
from tactile_force.edge.frames import FRAME_SHAPE

from .zoo import INPUT_CHANNELS, VARIANT_INPUTS, ModelSpec, check_variant, fold_linear_head


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


class Preprocess(nn.Module):
    """uint8 NHWC frame batch -> float NCHW network input (see module docstring)."""

    def __init__(self, input_scale: float = 1.0, kind: str = "rgb") -> None:
        super().__init__()
        if kind not in INPUT_CHANNELS:
            raise TactileForceError(f"input kind {kind!r}; expected 'rgb' or 'depth'")
        self.kind = kind
        self.k = scale_factor(input_scale)
        self.pool = nn.AvgPool2d(self.k, self.k) if self.k > 1 else nn.Identity()

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        x = x.permute(0, 3, 1, 2).float()
        if self.kind == "rgb":
            x = x.flip(1)  # BGR -> RGB
        return self.pool(x / 255.0)


class ForceNet(nn.Module):
    """Preprocess + model: raw uint8 NHWC batches in, force in N out, shape (N,).

    ``forward(rgb)`` for rgbmod, ``forward(depth)`` for d/dmod, ``forward(rgb, depth)``
    for rgbmod+d. Training calls this with uint8 batches, so the preprocessing it learns
    with is the one the exported graph runs. ``folded=True`` evaluates the head as the
    single folded linear map (what the ONNX graph holds).
    """

    def __init__(self, model: nn.Module, spec: ModelSpec, folded: bool = False) -> None:
        super().__init__()
        self.spec = ModelSpec(check_variant(spec.variant), float(spec.width), float(spec.input_scale))
        self.model = model
        self.input_names = VARIANT_INPUTS[self.spec.variant]
        self.pre = nn.ModuleDict({n: Preprocess(spec.input_scale, n) for n in self.input_names})
        self.folded = folded
        if folded:
            w, b = fold_linear_head(model)
            self.head = nn.Linear(w.shape[1], 1)
            with torch.no_grad():
                self.head.weight.copy_(w)
                self.head.bias.copy_(b)

    def forward(self, *frames: torch.Tensor) -> torch.Tensor:
        if len(frames) != len(self.input_names):
            raise TactileForceError(f"{self.spec.variant} takes inputs {self.input_names}, got {len(frames)} tensors")
        xs = [self.pre[n](f) for n, f in zip(self.input_names, frames)]
        if self.folded:
            return self.head(torch.cat(self.model.features(*xs), dim=1)).reshape(-1)
        return self.model(*xs).reshape(-1)
