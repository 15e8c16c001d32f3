"""Load and save checkpoints safely (``torch.load(weights_only=True)``) and strictly.

Accepted files: ``{"state_dict": ..., "optimizer": ...}`` (the authors' format), a bare
state_dict, either with an optional ``module.`` (DataParallel) prefix, and ours, which add
``"tactile_force": {"variant", "width", "input_scale", "blocks"}`` so export can infer the model
(a file without ``blocks``, the authors' included, has as many blocks per stage as its keys hold).
"""

from __future__ import annotations

import os
import pickle
from dataclasses import dataclass, field
from pathlib import Path

import torch
from tactile_force.edge.errors import TactileForceError
from torch import nn

from .zoo import RESNET18_BLOCKS, ModelSpec, build_model, check_blocks, check_variant

META_KEY = "tactile_force"


class CheckpointError(TactileForceError, ValueError):
    """A checkpoint file is unreadable, unsafe, or does not fit the requested model."""


@dataclass
class Checkpoint:
    """A loaded checkpoint: the state_dict (CPU tensors), our metadata if any, and its path."""

    path: Path
    state_dict: dict[str, torch.Tensor]
    meta: dict = field(default_factory=dict)


def load_checkpoint(path: str | os.PathLike) -> Checkpoint:
    """Read a .pth/.pth.tar file without executing code; CheckpointError naming the file otherwise."""
    p = Path(path)
    if not p.is_file():
        raise CheckpointError(f"{p}: checkpoint not found")
    if p.stat().st_size == 0:
        raise CheckpointError(f"{p}: checkpoint file is empty")
    try:
        obj = torch.load(p, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as exc:
        msg = str(exc)
        if "Weights only load failed" in msg:
            raise CheckpointError(
                f"{p}: refused: the file needs code execution to load (a pickled object, not plain tensors). "
                "Only weights-only checkpoints (dicts of tensors) are accepted. Re-save it with "
                "torch.save({'state_dict': model.state_dict()}, path).") from None
        raise CheckpointError(f"{p}: not a PyTorch checkpoint ({msg.splitlines()[0][:200]})") from None
    except Exception as exc:  # torch raises RuntimeError, KeyError, EOFError, ... for non-checkpoints
        first = (str(exc).splitlines() or [type(exc).__name__])[0][:200]
        raise CheckpointError(f"{p}: not a readable PyTorch checkpoint "
                              f"(truncated or another file type: {first})") from None
    meta: dict = {}
    if isinstance(obj, dict) and "state_dict" in obj:
        meta = check_metadata(obj.get(META_KEY), p)
        obj = obj["state_dict"]
    if not isinstance(obj, dict) or not obj or not all(isinstance(v, torch.Tensor) for v in obj.values()):
        raise CheckpointError(
            f"{p}: holds no state_dict; expected {{'state_dict': {{name: tensor}}}} or a bare {{name: tensor}} dict")
    sd = {str(k): v for k, v in obj.items()}
    if all(k.startswith("module.") for k in sd):
        sd = {k[len("module."):]: v for k, v in sd.items()}
    return Checkpoint(path=p, state_dict=sd, meta=dict(meta))


_PLAIN = (str, int, float, bool, type(None))


def _plain(value: object, depth: int = 0) -> bool:
    """True for JSON-like values: text, finite numbers, booleans, None, and lists/dicts of them."""
    if isinstance(value, float):
        return value == value and value not in (float("inf"), float("-inf"))
    if isinstance(value, _PLAIN):
        return True
    if depth >= 4:
        return False
    if isinstance(value, (list, tuple)):
        return all(_plain(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _plain(v, depth + 1) for k, v in value.items())
    return False


def _number(meta: dict, key: str, path: Path, lo: float, hi: float, what: str) -> None:
    v = meta.get(key)
    if key not in meta:
        return
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo < float(v) <= hi:
        raise CheckpointError(f"{path}: metadata '{META_KEY}.{key}' is {v!r}; expected {what}")


def check_metadata(raw: object, path: Path) -> dict:
    """Our checkpoint metadata, validated before any export work: a dict with text keys;
    ``variant`` a known variant, ``width`` a number in (0, 4], ``input_scale`` 1/k in (0, 1],
    every other value plain data (text, finite numbers, booleans, None, lists/dicts of them).
    None means no metadata. CheckpointError naming the file and the key otherwise."""
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise CheckpointError(f"{path}: metadata '{META_KEY}' is a {type(raw).__name__}; expected a dict such as "
                              "{'variant': 'rgbmod', 'width': 0.25, 'input_scale': 0.25, 'trained_on': '...'}")
    for key, value in raw.items():
        if not isinstance(key, str):
            raise CheckpointError(f"{path}: metadata '{META_KEY}' has the key {key!r}; expected text keys")
        if not _plain(value):
            raise CheckpointError(f"{path}: metadata '{META_KEY}.{key}' holds a {type(value).__name__}; expected text, "
                                  "a finite number, a boolean or lists/dicts of those (no tensors or objects)")
    if "variant" in raw:
        if not isinstance(raw["variant"], str):
            raise CheckpointError(f"{path}: metadata '{META_KEY}.variant' is {raw['variant']!r}; expected text such "
                                  "as 'rgbmod'")
        try:
            check_variant(raw["variant"])
        except TactileForceError as exc:
            raise CheckpointError(f"{path}: metadata '{META_KEY}.variant': {exc}") from None
    _number(raw, "width", path, 0.0, 4.0, "a channel width multiplier in (0, 4], e.g. 0.25")
    _number(raw, "input_scale", path, 0.0, 1.0, "an input scale 1/k in (0, 1], e.g. 0.25")
    if "blocks" in raw:
        try:
            check_blocks(raw["blocks"])
        except TactileForceError as exc:
            raise CheckpointError(f"{path}: metadata '{META_KEY}.blocks': {exc}") from None
    return dict(raw)


def _describe(keys: list[str], limit: int = 12) -> str:
    shown = ", ".join(keys[:limit])
    return shown + (f", ... ({len(keys) - limit} more)" if len(keys) > limit else "")


def load_into(model: nn.Module, state_dict: dict[str, torch.Tensor], source: str, variant: str) -> nn.Module:
    """Strictly load ``state_dict`` into ``model``; CheckpointError naming every bad key."""
    own = model.state_dict()
    missing = [k for k in own if k not in state_dict]
    unexpected = [k for k in state_dict if k not in own]
    misshaped = [f"{k} (file {tuple(state_dict[k].shape)}, model {tuple(v.shape)})"
                 for k, v in own.items() if k in state_dict and tuple(state_dict[k].shape) != tuple(v.shape)]
    if missing or unexpected or misshaped:
        parts = [f"{source}: does not fit variant '{variant}'"]
        if missing:
            parts.append(f"missing keys: {_describe(missing)}")
        if unexpected:
            parts.append(f"unexpected keys: {_describe(unexpected)}")
        if misshaped:
            parts.append(f"mis-shaped keys: {_describe(misshaped)}")
        for key in ("conv1.weight", "model_rgb.conv1.weight"):
            if key in state_dict and state_dict[key].dim() == 4:
                c_out, c_in = state_dict[key].shape[:2]
                parts.append(f"the file's {key} is {c_in} -> {c_out} channels (width {c_out / 64:g}, "
                             f"{'RGB' if c_in == 3 else 'depth' if c_in == 1 else str(c_in) + '-channel'} input)")
                break
        parts.append("check --variant and --width (the authors' D is saved without a prefix, RGBmod+D "
                     "with model_rgb./model_mask./model_mask_before_fc.)")
        raise CheckpointError("; ".join(parts))
    model.load_state_dict(state_dict, strict=True)
    return model.eval()


def blocks_in(state_dict: dict[str, torch.Tensor]) -> tuple[int, int, int, int]:
    """Residual blocks per stage that a state_dict's keys hold (``layer<i>.<j>.`` of its first
    trunk; RGBmod+D's two trunks have the same); ResNet-18's when it has no such keys."""
    import re

    found: dict[str, list[int]] = {}
    for key in state_dict:
        m = re.match(r"^(.*?)layer([1-4])\.(\d+)\.", key)
        if m:
            found.setdefault(m.group(1), [0, 0, 0, 0])
            stage = found[m.group(1)]
            stage[int(m.group(2)) - 1] = max(stage[int(m.group(2)) - 1], int(m.group(3)) + 1)
    counts = next(iter(found.values()), None)
    if counts is None or min(counts) < 1:
        return RESNET18_BLOCKS
    try:
        return check_blocks(counts)
    except TactileForceError:
        return RESNET18_BLOCKS  # load_into names the keys that do not fit


def resolve_spec(ckpt: Checkpoint, variant: str | None = None, width: float | None = None,
                 input_scale: float | None = None) -> ModelSpec:
    """Model spec from explicit arguments, else the checkpoint's metadata, else paper defaults
    (blocks per stage: the metadata's, else what the keys hold)."""
    meta = ckpt.meta
    v = variant or meta.get("variant")
    if not v:
        raise CheckpointError(
            f"{ckpt.path}: the file does not say which model it holds; pass --variant (rgbmod, d, dmod, rgbmod+d)")
    blocks = check_blocks(meta["blocks"]) if "blocks" in meta else blocks_in(ckpt.state_dict)
    return ModelSpec(variant=check_variant(v),
                     width=float(width if width is not None else meta.get("width", 1.0)),
                     input_scale=float(input_scale if input_scale is not None else meta.get("input_scale", 1.0)),
                     blocks=blocks)


def model_from_checkpoint(path: str | os.PathLike, variant: str | None = None, width: float | None = None,
                          input_scale: float | None = None) -> tuple[nn.Module, ModelSpec, Checkpoint]:
    """Load a checkpoint into a strictly matching model (eval mode)."""
    ckpt = load_checkpoint(path)
    spec = resolve_spec(ckpt, variant, width, input_scale)
    model = load_into(build_model(spec.variant, spec.width, spec.blocks), ckpt.state_dict, str(ckpt.path),
                      spec.variant)
    return model, spec, ckpt


def save_checkpoint(path: str | os.PathLike, model: nn.Module, spec: ModelSpec, extra: dict | None = None) -> Path:
    """Save ``{"state_dict", "tactile_force": spec + extra}`` atomically (temp file + rename)."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    meta = {**spec.as_dict(), **(extra or {})}
    tmp = p.with_name(f".{p.name}.tmp")
    torch.save({"state_dict": model.state_dict(), META_KEY: meta}, tmp)
    os.replace(tmp, p)
    return p
