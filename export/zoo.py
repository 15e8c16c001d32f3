"""The paper's networks (RGBmod, D, Dmod, RGBmod+D) on a ResNet-18 trunk written here.

State-dict keys match torchvision's ``ResNet(BasicBlock, [2, 2, 2, 2])`` exactly, so the
paper authors' checkpoints load with ``strict=True``. A width multiplier scales every
channel count (64w, 128w, 256w, 512w) for compact variants; ``width=1`` is the paper's.
``blocks`` sets the residual blocks per stage (layer1..layer4): ResNet-18's ``(2, 2, 2, 2)``
by default, fewer (e.g. ``(1, 1, 1, 1)``) for cheaper students; the keys of the blocks that
remain are torchvision's (``layer1.0.*``).

Every model maps network input tensors (float, NCHW, RGB or depth in [0, 1]) to the force
in N, shape (N, 1), and exposes its pooled features and its purely linear head so the
export can fold the head into one exact linear map (see :func:`fold_linear_head`).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tactile_force.edge.bundle.manifest import VARIANTS
from tactile_force.edge.bundle.manifest_graph import stage_channels
from tactile_force.edge.errors import TactileForceError
from torch import nn

#: Network inputs of each variant, in forward() order; 'rgb' has 3 channels, 'depth' 1.
VARIANT_INPUTS: dict[str, tuple[str, ...]] = {
    "rgbmod": ("rgb",),
    "d": ("depth",),
    "dmod": ("depth",),
    "rgbmod+d": ("rgb", "depth"),
}
INPUT_CHANNELS = {"rgb": 3, "depth": 1}


class UnknownVariantError(TactileForceError, ValueError):
    """A variant name that is not one of :data:`VARIANTS`."""


def check_variant(variant: str) -> str:
    """Return the variant name normalised to lower case, or raise naming the choices."""
    v = str(variant).strip().lower()
    if v not in VARIANTS:
        raise UnknownVariantError(f"unknown model variant {variant!r}; expected one of {', '.join(VARIANTS)}")
    return v


#: Residual blocks per stage of ResNet-18 (the paper's trunk; what a record without ``blocks`` means).
RESNET18_BLOCKS: tuple[int, int, int, int] = (2, 2, 2, 2)
#: Most blocks a stage may have (ResNet-34's largest stage has 6).
MAX_BLOCKS = 8


def check_blocks(blocks: object) -> tuple[int, int, int, int]:
    """``blocks`` as a tuple of four ints in [1, :data:`MAX_BLOCKS`], or raise naming what was expected."""
    if not (isinstance(blocks, (tuple, list)) and len(blocks) == 4
            and all(isinstance(b, int) and not isinstance(b, bool) and 1 <= b <= MAX_BLOCKS for b in blocks)):
        raise TactileForceError(f"blocks {blocks!r}: expected four residual-block counts per stage, each an integer "
                                f"1..{MAX_BLOCKS}, e.g. (2, 2, 2, 2) (ResNet-18) or (1, 1, 1, 1)")
    a, b, c, d = (int(n) for n in blocks)
    return a, b, c, d


def blocks_tag(blocks: tuple[int, ...]) -> str:
    """'' for ResNet-18's blocks, else '-b1111' (a name suffix for students and configs)."""
    return "" if tuple(blocks) == RESNET18_BLOCKS else "-b" + "".join(str(b) for b in blocks)


def channels(width: float) -> tuple[int, int, int, int]:
    """Channel counts of layer1..layer4 for a width multiplier (64, 128, 256, 512 at 1.0)."""
    if not (0 < float(width) <= 4):
        raise TactileForceError(f"width multiplier {width!r} out of range; expected 0 < width <= 4")
    return stage_channels(width)


class BasicBlock(nn.Module):
    """torchvision's BasicBlock: two 3x3 convs + BN, identity or 1x1-conv shortcut."""

    def __init__(self, c_in: int, c_out: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(c_in, c_out, 3, stride, 1, bias=False)
        self.bn1 = nn.BatchNorm2d(c_out)
        self.relu = nn.ReLU(inplace=True)
        self.conv2 = nn.Conv2d(c_out, c_out, 3, 1, 1, bias=False)
        self.bn2 = nn.BatchNorm2d(c_out)
        self.downsample = None
        if stride != 1 or c_in != c_out:
            self.downsample = nn.Sequential(nn.Conv2d(c_in, c_out, 1, stride, bias=False), nn.BatchNorm2d(c_out))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        identity = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return self.relu(out + identity)


def _stage(c_in: int, c_out: int, stride: int, n: int) -> nn.Sequential:
    """One stage: a (strided) block c_in -> c_out, then n - 1 blocks c_out -> c_out."""
    return nn.Sequential(BasicBlock(c_in, c_out, stride), *(BasicBlock(c_out, c_out) for _ in range(n - 1)))


class ResNet18(nn.Module):
    """ResNet-18 trunk with torchvision key names; ``fc_out=None`` leaves out ``fc``."""

    def __init__(self, in_channels: int = 3, width: float = 1.0, fc_out: int | None = 1000,
                 blocks: tuple[int, int, int, int] = RESNET18_BLOCKS) -> None:
        super().__init__()
        c1, c2, c3, c4 = channels(width)
        n1, n2, n3, n4 = self.blocks = check_blocks(blocks)
        self.width = float(width)
        self.conv1 = nn.Conv2d(in_channels, c1, 7, 2, 3, bias=False)
        self.bn1 = nn.BatchNorm2d(c1)
        self.relu = nn.ReLU(inplace=True)
        self.maxpool = nn.MaxPool2d(3, 2, 1)
        self.layer1 = _stage(c1, c1, 1, n1)
        self.layer2 = _stage(c1, c2, 2, n2)
        self.layer3 = _stage(c2, c3, 2, n3)
        self.layer4 = _stage(c3, c4, 2, n4)
        self.avgpool = nn.AdaptiveAvgPool2d((1, 1))
        if fc_out is not None:
            self.fc = nn.Linear(c4, fc_out)
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")

    @staticmethod
    def _pool(x: torch.Tensor) -> torch.Tensor:
        # == flatten(avgpool(x), 1); a plain mean exports as one ReduceMean
        return x.mean(dim=(2, 3))

    def pyramid(self, x: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Globally pooled layer2, layer3, layer4 features: (N, c2), (N, c3), (N, c4)."""
        x = self.maxpool(self.relu(self.bn1(self.conv1(x))))
        x = self.layer2(self.layer1(x))
        p2 = self._pool(x)
        x = self.layer3(x)
        p3 = self._pool(x)
        x = self.layer4(x)
        return p2, p3, self._pool(x)

    def pooled(self, x: torch.Tensor) -> torch.Tensor:
        """Globally pooled layer4 features (N, c4)."""
        return self.pyramid(x)[2]


class RGBmod(ResNet18):
    """The paper's RGBmod: pooled layer2 -> fc1, layer3 -> fc2, layer4; concat -> fc4.

    Like the authors' class it also holds the unused ``fc`` (c4 -> 1000) and ``fc3``
    (c4 -> 1), so their checkpoints load strictly. ``fc4_out`` is 1 for RGBmod and c4 for
    the RGB branch of RGBmod+D. ``in_channels=1`` and ``unused_heads=False`` give Dmod.
    """

    def __init__(self, width: float = 1.0, in_channels: int = 3, fc4_out: int = 1, unused_heads: bool = True,
                 blocks: tuple[int, int, int, int] = RESNET18_BLOCKS) -> None:
        super().__init__(in_channels, width, fc_out=1000 if unused_heads else None, blocks=blocks)
        _, c2, c3, c4 = channels(width)
        self.fc1 = nn.Linear(c2, c4)
        self.fc2 = nn.Linear(c3, c4)
        if unused_heads:
            self.fc3 = nn.Linear(c4, 1)
        self.fc4 = nn.Linear(3 * c4, fc4_out)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        p2, p3, p4 = self.pyramid(x)
        return self.fc4(torch.cat((self.fc1(p2), self.fc2(p3), p4), dim=1))

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        return list(self.pyramid(x))

    def linear_head(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(W, b) in float64 with forward(x) == cat(features(x)) @ W.T + b."""
        w1, b1 = self.fc1.weight.double(), self.fc1.bias.double()
        w2, b2 = self.fc2.weight.double(), self.fc2.bias.double()
        w4, b4 = self.fc4.weight.double(), self.fc4.bias.double()
        c4 = w1.shape[0]
        w4a, w4b, w4c = w4[:, :c4], w4[:, c4:2 * c4], w4[:, 2 * c4:]
        w = torch.cat((w4a @ w1, w4b @ w2, w4c), dim=1)
        return w, w4a @ b1 + w4b @ b2 + b4


class D(ResNet18):
    """The paper's D: torchvision resnet18 with a 1-channel conv1 and fc c4 -> 1.

    Saved without a key prefix (the authors train and save ``D().model``).
    """

    def __init__(self, width: float = 1.0, blocks: tuple[int, int, int, int] = RESNET18_BLOCKS) -> None:
        super().__init__(in_channels=1, width=width, fc_out=1, blocks=blocks)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc(self.pooled(x))

    def features(self, x: torch.Tensor) -> list[torch.Tensor]:
        return [self.pooled(x)]

    def linear_head(self) -> tuple[torch.Tensor, torch.Tensor]:
        return self.fc.weight.double(), self.fc.bias.double()


class Dmod(RGBmod):
    """D with RGBmod's multi-level head (not in the authors' code): 1-channel input."""

    def __init__(self, width: float = 1.0, blocks: tuple[int, int, int, int] = RESNET18_BLOCKS) -> None:
        super().__init__(width=width, in_channels=1, fc4_out=1, unused_heads=False, blocks=blocks)


class RGBmodD(nn.Module):
    """The authors' ``RGBandDToForce``: RGBmod branch (fc4 -> c4) + D trunk, fc1 -> 16 -> fc2.

    Keys: ``model_rgb.*``, ``model_mask.*`` (including its unused ``fc`` c4 -> 1000) and the
    same depth modules again as ``model_mask_before_fc.{0,1,4,5,6,7}.*`` (shared tensors).
    There is no activation between fc1 and fc2, so the whole head is linear.
    """

    def __init__(self, width: float = 1.0, blocks: tuple[int, int, int, int] = RESNET18_BLOCKS) -> None:
        super().__init__()
        c4 = channels(width)[3]
        self.blocks = check_blocks(blocks)
        self.model_rgb = RGBmod(width=width, in_channels=3, fc4_out=c4, unused_heads=True, blocks=blocks)
        self.model_mask = ResNet18(in_channels=1, width=width, fc_out=1000, blocks=blocks)
        m = self.model_mask
        self.model_mask_before_fc = nn.Sequential(m.conv1, m.bn1, m.relu, m.maxpool, m.layer1, m.layer2, m.layer3,
                                                  m.layer4, m.avgpool)
        self.fc1 = nn.Linear(2 * c4, 16)
        self.fc2 = nn.Linear(16, 1)

    def forward(self, rgb: torch.Tensor, depth: torch.Tensor) -> torch.Tensor:
        y1 = self.model_rgb(rgb)
        y2 = torch.flatten(self.model_mask_before_fc(depth), 1)
        return self.fc2(self.fc1(torch.cat((y1, y2), dim=1)))

    def features(self, rgb: torch.Tensor, depth: torch.Tensor) -> list[torch.Tensor]:
        return self.model_rgb.features(rgb) + [self.model_mask.pooled(depth)]

    def linear_head(self) -> tuple[torch.Tensor, torch.Tensor]:
        wr, br = self.model_rgb.linear_head()
        c4 = wr.shape[0]
        w1, b1 = self.fc1.weight.double(), self.fc1.bias.double()
        w2, b2 = self.fc2.weight.double(), self.fc2.bias.double()
        w1r, w1d = w1[:, :c4], w1[:, c4:]
        w = w2 @ torch.cat((w1r @ wr, w1d), dim=1)
        return w, w2 @ (w1r @ br + b1) + b2


_CLASSES = {"rgbmod": RGBmod, "d": D, "dmod": Dmod, "rgbmod+d": RGBmodD}


@dataclass(frozen=True)
class ModelSpec:
    """What identifies an architecture: variant, width multiplier, input scale (1/k) and
    residual blocks per stage (ResNet-18's (2, 2, 2, 2) unless fewer)."""

    variant: str
    width: float = 1.0
    input_scale: float = 1.0
    blocks: tuple[int, int, int, int] = RESNET18_BLOCKS

    def __post_init__(self) -> None:
        object.__setattr__(self, "blocks", check_blocks(self.blocks))

    def as_dict(self) -> dict:
        return {"variant": self.variant, "width": self.width, "input_scale": self.input_scale,
                "blocks": list(self.blocks)}


def build_model(variant: str, width: float = 1.0, blocks: tuple[int, int, int, int] = RESNET18_BLOCKS) -> nn.Module:
    """A freshly initialised model of ``variant`` ('rgbmod', 'd', 'dmod', 'rgbmod+d') with
    ``blocks`` residual blocks per stage."""
    return _CLASSES[check_variant(variant)](width=width, blocks=check_blocks(blocks))


def fold_linear_head(model: nn.Module) -> tuple[torch.Tensor, torch.Tensor]:
    """The model's whole head as one linear map, float32 W (1, F) and b (1,).

    Exact up to float rounding: computed in float64 from the trained layers.
    """
    w, b = model.linear_head()  # type: ignore[operator]
    return w.float(), b.float()
