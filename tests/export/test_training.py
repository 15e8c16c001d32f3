"""The one training loop (export/training.py): deterministic, learns, augments sensibly."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from tactile_force.edge.errors import OptionsError
from tactile_force.export import ModelSpec
from tactile_force.export.preprocess import ForceNet
from tactile_force.export.training import Augment, Frames, TrainOptions, augment_batch, preprocess, train_network
from tactile_force.export.zoo import build_model


def _frames(n: int, seed: int) -> Frames:
    rng = np.random.default_rng(seed)
    rgb = rng.integers(0, 256, (n, 320, 240, 3), dtype=np.uint8)
    level = rng.uniform(0, 1, n)
    rgb = (rgb * 0.3 + level[:, None, None, None] * 170).astype(np.uint8)
    return Frames({"rgb": rgb}, (1 + 10 * level).astype(np.float32))  # force follows brightness


def test_same_seed_same_weights_and_it_learns():
    spec = ModelSpec("rgbmod", 0.125, 1 / 8)
    train, val = _frames(96, 0), _frames(24, 1)
    opts = TrainOptions(epochs=4, batch=16, seed=3, threads=1, augment=Augment())
    a = train_network(spec, train, val, opts)
    b = train_network(spec, train, val, opts)
    for (k, va), (_, vb) in zip(a.model.state_dict().items(), b.model.state_dict().items()):
        assert torch.equal(va, vb), k
    assert [e.val_re for e in a.history] == [e.val_re for e in b.history]
    assert a.history[-1].train_l1 < a.history[0].train_l1
    assert 1 <= a.best_epoch <= 4
    c = train_network(spec, train, val, TrainOptions(epochs=1, batch=16, seed=4, threads=1))
    assert not torch.equal(next(iter(c.model.state_dict().values())), next(iter(a.model.state_dict().values())))


def test_augmentation_keeps_shape_and_stays_close():
    gen = torch.Generator().manual_seed(0)
    ramp = torch.linspace(0.2, 0.8, 40)[:, None] + torch.linspace(0, 0.1, 30)[None, :]
    x = ramp.expand(8, 3, 40, 30).clone()  # smooth, like a gel image at network resolution
    y = augment_batch(x, Augment(gain=0.1, offset=0.05, noise=0.01, shift_px=1), gen)
    assert y.shape == x.shape and not torch.equal(x, y)
    assert float((y - x).abs().mean()) < 0.1
    same = augment_batch(x, Augment(gain=0, offset=0, noise=0, shift_px=0), gen)
    assert torch.equal(same, x)


def test_network_inputs_are_plain_nchw():
    # channels-last inputs send training through oneDNN kernels that corrupt the heap on some shapes
    spec = ModelSpec("rgbmod", 0.125, 1 / 8)
    net = ForceNet(build_model(spec.variant, spec.width), spec)
    (x,) = preprocess(net, _frames(5, 0).inputs)
    assert x.shape == (5, 3, 40, 30) and x.is_contiguous()


@pytest.mark.parametrize("threads", [0, -2, 1.5, "2", True])
def test_threads_must_be_a_positive_integer(threads):
    with pytest.raises(OptionsError, match="threads"):
        TrainOptions(threads=threads)
