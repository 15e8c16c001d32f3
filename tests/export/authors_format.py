"""Checkpoints in the paper authors' exact format (key names and shapes), random weights.

The authors' key names and shapes are written out here from their model definitions
(torchvision resnet18 + their heads), independently of tactile_force.export.zoo, so a
drift in the zoo fails the tests instead of being mirrored by them.
"""

from __future__ import annotations

from pathlib import Path

import torch


def resnet18_keys(in_channels: int, fc_out: int | None, prefix: str = "") -> dict[str, tuple]:
    """torchvision resnet18 state_dict names -> shapes (BN buffers included)."""
    keys: dict[str, tuple] = {}

    def bn(name: str, c: int) -> None:
        for s in ("weight", "bias", "running_mean", "running_var"):
            keys[f"{prefix}{name}.{s}"] = (c,)
        keys[f"{prefix}{name}.num_batches_tracked"] = ()

    keys[f"{prefix}conv1.weight"] = (64, in_channels, 7, 7)
    bn("bn1", 64)
    c_in = 64
    for li, c in enumerate((64, 128, 256, 512), start=1):
        for b in range(2):
            src = c_in if b == 0 else c
            keys[f"{prefix}layer{li}.{b}.conv1.weight"] = (c, src, 3, 3)
            bn(f"layer{li}.{b}.bn1", c)
            keys[f"{prefix}layer{li}.{b}.conv2.weight"] = (c, c, 3, 3)
            bn(f"layer{li}.{b}.bn2", c)
            if b == 0 and li > 1:
                keys[f"{prefix}layer{li}.{b}.downsample.0.weight"] = (c, src, 1, 1)
                bn(f"layer{li}.{b}.downsample.1", c)
        c_in = c
    if fc_out is not None:
        keys[f"{prefix}fc.weight"] = (fc_out, 512)
        keys[f"{prefix}fc.bias"] = (fc_out,)
    return keys


def rgbmod_keys(prefix: str = "", fc4_out: int = 1) -> dict[str, tuple]:
    keys = resnet18_keys(3, 1000, prefix)
    for name, (o, i) in {"fc1": (512, 128), "fc2": (512, 256), "fc3": (1, 512), "fc4": (fc4_out, 1536)}.items():
        keys[f"{prefix}{name}.weight"] = (o, i)
        keys[f"{prefix}{name}.bias"] = (o,)
    return keys


def authors_keys(variant: str) -> dict[str, tuple]:
    """The authors' checkpoint keys for 'rgbmod', 'd' or 'rgbmod+d'."""
    if variant == "rgbmod":
        return rgbmod_keys()
    if variant == "d":
        return resnet18_keys(1, 1)
    if variant == "rgbmod+d":
        keys = rgbmod_keys("model_rgb.", fc4_out=512)
        keys.update(resnet18_keys(1, 1000, "model_mask."))
        seq = {"conv1": "0", "bn1": "1", "layer1": "4", "layer2": "5", "layer3": "6", "layer4": "7"}
        for k, shape in resnet18_keys(1, None).items():
            head, rest = k.split(".", 1)
            keys[f"model_mask_before_fc.{seq[head]}.{rest}"] = shape
        keys.update({"fc1.weight": (16, 1024), "fc1.bias": (16,), "fc2.weight": (1, 16), "fc2.bias": (1,)})
        return keys
    raise ValueError(variant)


def random_state(keys: dict[str, tuple], seed: int = 0) -> dict:
    """Plausible trained-looking tensors: He-normal convs, BN stats away from identity."""
    g = torch.Generator().manual_seed(seed)
    sd = {}
    for k, shape in keys.items():
        if k.endswith("num_batches_tracked"):
            sd[k] = torch.tensor(1000, dtype=torch.long)
        elif k.endswith("running_var"):
            sd[k] = 0.5 + torch.rand(shape, generator=g)
        elif k.endswith("running_mean"):
            sd[k] = 0.1 * torch.randn(shape, generator=g)
        elif len(shape) == 4:
            fan_in = shape[1] * shape[2] * shape[3]
            sd[k] = torch.randn(shape, generator=g) * (2.0 / fan_in) ** 0.5
        elif len(shape) == 1 and k.endswith(".weight"):  # BatchNorm scale (Linear weights are 2-D)
            sd[k] = 1.0 + 0.1 * torch.randn(shape, generator=g)
        elif len(shape) == 2:
            sd[k] = torch.randn(shape, generator=g) / shape[1] ** 0.5
        else:
            sd[k] = 0.05 * torch.randn(shape, generator=g)
    # the model_mask_before_fc.* tensors are the same tensors as model_mask.* in the authors' files
    seq = {"0": "conv1", "1": "bn1", "4": "layer1", "5": "layer2", "6": "layer3", "7": "layer4"}
    for k in list(sd):
        if k.startswith("model_mask_before_fc."):
            idx, rest = k[len("model_mask_before_fc."):].split(".", 1)
            sd[k] = sd[f"model_mask.{seq[idx]}.{rest}"]
    return sd


def save_authors_checkpoint(path: Path, variant: str, seed: int = 0, wrap: bool = True) -> Path:
    sd = random_state(authors_keys(variant), seed)
    torch.save({"state_dict": sd, "optimizer": {"state": {}, "param_groups": []}} if wrap else sd, path)
    return path
