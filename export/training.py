"""The one student-training loop: used by ``tactile-force compress`` and the reference recipe.

Recipe (the paper's hyperparameters where they fit a CPU budget): Adam, L1 loss, batch 64,
cosine-decayed learning rate, weights from scratch, seeded; the epoch with the lowest RE on
the validation targets is kept. Targets are forces in N: labels, a teacher's outputs
(distillation), or a mix of both.

Preprocessing is the exported graph's own (:class:`ForceNet`'s ``pre`` modules); it has no
parameters, so it is applied once to all frames and kept in memory as float32 at the
network's input resolution. The optional augmentation models real sensor variability and
acts on those tensors: per-channel LED gain and offset, Gaussian noise, and small shifts
(whole network-input pixels, edges replicated).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
from tactile_force.edge.data.metrics import error_stats
from tactile_force.edge.errors import OptionsError
from torch import nn

from .preprocess import ForceNet
from .zoo import ModelSpec, blocks_tag, build_model


@dataclass(frozen=True)
class Augment:
    """Sensor-variability augmentation, drawn per training sample and step.

    gain: per-channel LED gain drawn from [1 - gain, 1 + gain]; offset: per-channel offset in
    [-offset, +offset] (input units, 1.0 = 255 levels); noise: Gaussian sigma (same units);
    shift_px: shifts of up to this many network-input pixels in each direction."""

    gain: float = 0.08
    offset: float = 0.03
    noise: float = 0.01
    shift_px: int = 1


@dataclass(frozen=True)
class TrainOptions:
    """epochs, lr (Adam, cosine decay to 0), batch, seed, threads (None: all cores),
    augment (None: no augmentation), eval_batch (frames per inference batch)."""

    epochs: int = 30
    lr: float = 1e-3
    batch: int = 64
    seed: int = 0
    threads: int | None = None
    augment: Augment | None = None
    eval_batch: int = 256

    def __post_init__(self) -> None:
        if self.threads is not None and (isinstance(self.threads, bool) or not isinstance(self.threads, int)
                                         or self.threads < 1):
            raise OptionsError(f"threads {self.threads!r}: expected a positive integer (torch threads for "
                               "training) or None (all cores)")


@dataclass
class Frames:
    """Raw network inputs by name ('rgb': (N,320,240,3) uint8 BGR, 'depth': (N,320,240,1) uint8)
    and the target force of each frame (N,) in N."""

    inputs: dict[str, np.ndarray]
    targets: np.ndarray

    def __len__(self) -> int:
        return int(self.targets.shape[0])


@dataclass
class EpochLog:
    """One epoch: mean training L1 (N), RE and MAE (N) on the validation targets."""

    epoch: int
    train_l1: float
    val_re: float
    val_mae: float
    seconds: float


@dataclass
class TrainResult:
    """The trained network (best epoch loaded, eval mode), which epoch that was, the log."""

    net: ForceNet
    best_epoch: int
    history: list[EpochLog] = field(default_factory=list)
    seconds: float = 0.0

    @property
    def model(self) -> nn.Module:
        return self.net.model


def preprocess(net: ForceNet, inputs: dict[str, np.ndarray], chunk: int = 256) -> list[torch.Tensor]:
    """Network inputs (float32 NCHW, contiguous, in forward order) of raw uint8 frames, through ``net.pre``.

    ``net.pre`` permutes NHWC frames, so its output is laid out channels-last; it is copied to
    plain NCHW here. With a channels-last input every layer runs channels-last, and oneDNN's
    channels-last convolution backward writes out of bounds with more than one thread on some
    shapes (a 1x1 stride-2 convolution of 8 channels at 10x8 on an odd-sized batch, in the
    width-0.125 RGBmod at input 1/8): the process aborts (double free) or segfaults.
    """
    xs = []
    with torch.no_grad():
        for name in net.input_names:
            src = inputs[name]
            n = src.shape[0]
            parts = [net.pre[name](torch.from_numpy(np.ascontiguousarray(src[i:i + chunk])))
                     for i in range(0, n, chunk)]
            xs.append(torch.cat(parts).contiguous() if parts else torch.empty(0))
    return xs


def predict(model: nn.Module, xs: list[torch.Tensor], batch: int = 256) -> np.ndarray:
    """Forces (N,) float32 of preprocessed inputs ``xs`` (eval mode, no grad)."""
    model.eval()
    with torch.no_grad():
        outs = [model(*[x[i:i + batch] for x in xs]).reshape(-1) for i in range(0, len(xs[0]), batch)]
    return torch.cat(outs).numpy() if outs else np.empty(0, np.float32)


def augment_batch(x: torch.Tensor, a: Augment, gen: torch.Generator) -> torch.Tensor:
    """A sensor-variability augmented copy of a float NCHW batch (see :class:`Augment`)."""
    n, c = x.shape[:2]
    gain = 1.0 + (torch.rand((n, c, 1, 1), generator=gen) * 2 - 1) * a.gain
    offset = (torch.rand((n, c, 1, 1), generator=gen) * 2 - 1) * a.offset
    y = x * gain + offset
    if a.noise > 0:
        y = y + torch.randn(y.shape, generator=gen) * a.noise
    if a.shift_px > 0:
        s = a.shift_px
        dy, dx = (int(v) for v in torch.randint(-s, s + 1, (2,), generator=gen))
        if dy or dx:
            y = nn.functional.pad(y, (s, s, s, s), mode="replicate")[:, :, s - dy:s - dy + x.shape[2],
                                                                    s - dx:s - dx + x.shape[3]]
    return y


def train_network(spec: ModelSpec, train: Frames, val: Frames, options: TrainOptions | None = None,
                  log: Callable[[EpochLog], None] | None = None, show_progress: bool = False,
                  desc: str = "") -> TrainResult:
    """Train a fresh ``spec`` network on ``train``; keep the epoch with the lowest RE on ``val``.

    Parameters
    ----------
    spec
        Variant, width multiplier and input scale of the network to build.
    train, val
        Raw frames and target forces (N): labels or a teacher's outputs.
    options
        :class:`TrainOptions` (epochs, learning rate, batch, seed, augmentation).
    log
        Called after every epoch with its :class:`EpochLog`.
    show_progress, desc
        A tqdm bar over the epochs.

    Returns
    -------
    TrainResult with the best epoch's weights loaded (eval mode).
    """
    o = options or TrainOptions()
    torch.manual_seed(o.seed)
    np.random.seed(o.seed)
    torch.set_num_threads(o.threads or os.cpu_count() or 1)
    net = ForceNet(build_model(spec.variant, spec.width, spec.blocks), spec)
    x_tr, x_va = preprocess(net, train.inputs), preprocess(net, val.inputs)
    y_tr = torch.from_numpy(np.asarray(train.targets, np.float32))
    y_va = np.asarray(val.targets, np.float64)
    model = net.model
    opt = torch.optim.Adam(model.parameters(), lr=o.lr)
    steps = math.ceil(len(train) / o.batch)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=max(1, o.epochs * steps))
    loss_fn = nn.L1Loss()
    gen = torch.Generator().manual_seed(o.seed)
    aug_gen = torch.Generator().manual_seed(o.seed + 1)
    best: tuple[float, dict | None, int] = (math.inf, None, -1)
    history: list[EpochLog] = []
    t0 = time.perf_counter()
    bar = None
    if show_progress:
        from tqdm import tqdm

        bar = tqdm(total=o.epochs, desc=desc or spec_name(spec), unit="epoch", leave=False)
    try:
        for epoch in range(o.epochs):
            model.train()
            order = torch.randperm(len(train), generator=gen)
            total = 0.0
            for s in range(steps):
                b = order[s * o.batch:(s + 1) * o.batch]
                if len(b) < 2:  # BatchNorm needs two samples
                    continue
                xb = [x[b] for x in x_tr]
                if o.augment is not None:
                    xb = [augment_batch(x, o.augment, aug_gen) for x in xb]
                opt.zero_grad(set_to_none=True)
                loss = loss_fn(model(*xb).reshape(-1), y_tr[b])
                loss.backward()
                opt.step()
                sched.step()
                total += float(loss.detach()) * len(b)
            val_stats = error_stats(predict(model, x_va, o.eval_batch), y_va)
            entry = EpochLog(epoch + 1, total / max(1, len(train)), val_stats.re_mean, val_stats.mae_mean,
                             time.perf_counter() - t0)
            history.append(entry)
            if log is not None:
                log(entry)
            if bar is not None:
                bar.set_postfix(l1=f"{entry.train_l1:.3f}", val_re=f"{entry.val_re:.3f}")
                bar.update(1)
            score = entry.val_re if math.isfinite(entry.val_re) else entry.val_mae
            if score < best[0]:
                best = (score, {k: v.detach().clone() for k, v in model.state_dict().items()}, epoch + 1)
    finally:
        if bar is not None:
            bar.close()
    if best[1] is not None:
        model.load_state_dict(best[1])
    model.eval()
    return TrainResult(net=net, best_epoch=best[2], history=history, seconds=time.perf_counter() - t0)


def spec_name(spec: ModelSpec) -> str:
    """'rgbmod-w0.25-s4' for a ModelSpec (the reference recipe's naming; '-b1111' appended for
    fewer blocks per stage than ResNet-18's)."""
    k = round(1.0 / spec.input_scale)
    return f"{spec.variant}-w{spec.width:g}-s{k}{blocks_tag(spec.blocks)}"
