"""Model zoo key layout, strict checkpoint loading, preprocessing and head folding."""

from __future__ import annotations

import os
import pickle

import cv2
import numpy as np
import pytest
import torch
from tactile_force.export import (
    CheckpointError,
    ForceNet,
    ModelSpec,
    Preprocess,
    UnknownVariantError,
    build_model,
    load_checkpoint,
    model_from_checkpoint,
    save_checkpoint,
)

from tests.export.authors_format import authors_keys, random_state, save_authors_checkpoint


@pytest.mark.parametrize("variant", ["rgbmod", "d", "rgbmod+d"])
def test_zoo_keys_and_shapes_match_the_authors_files(variant):
    want = authors_keys(variant)
    got = {k: tuple(v.shape) for k, v in build_model(variant).state_dict().items()}
    assert got == want


@pytest.mark.parametrize("variant", ["rgbmod", "d", "rgbmod+d"])
def test_authors_checkpoint_loads_strictly(tmp_path, variant):
    path = save_authors_checkpoint(tmp_path / "ckpt.pth.tar", variant, seed=1)
    model, spec, ckpt = model_from_checkpoint(path, variant=variant)
    assert spec.variant == variant and spec.width == 1.0 and not model.training
    ref = torch.load(path, weights_only=True)["state_dict"]
    for k, v in model.state_dict().items():
        assert torch.equal(v, ref[k]), k


def test_bare_state_dict_with_dataparallel_prefix_loads(tmp_path):
    sd = {f"module.{k}": v for k, v in random_state(authors_keys("d")).items()}
    torch.save(sd, tmp_path / "d.pth")
    model, spec, _ = model_from_checkpoint(tmp_path / "d.pth", variant="d")
    assert torch.equal(model.state_dict()["fc.weight"], sd["module.fc.weight"])


def test_missing_extra_and_misshaped_keys_are_named(tmp_path):
    sd = random_state(authors_keys("rgbmod"))
    del sd["fc4.bias"]
    sd["layer9.extra.weight"] = torch.zeros(3)
    sd["fc2.weight"] = torch.zeros(512, 255)
    torch.save({"state_dict": sd}, tmp_path / "bad.pth")
    with pytest.raises(CheckpointError) as err:
        model_from_checkpoint(tmp_path / "bad.pth", variant="rgbmod")
    msg = str(err.value)
    assert "missing keys: fc4.bias" in msg
    assert "unexpected keys: layer9.extra.weight" in msg
    assert "fc2.weight (file (512, 255), model (512, 256))" in msg


def test_wrong_variant_for_file_names_the_difference(tmp_path):
    path = save_authors_checkpoint(tmp_path / "d.pth", "d")
    with pytest.raises(CheckpointError, match=r"conv1.weight \(file \(64, 1, 7, 7\), model \(64, 3, 7, 7\)\)"):
        model_from_checkpoint(path, variant="rgbmod")


def test_unknown_variant_name():
    with pytest.raises(UnknownVariantError, match="expected one of rgbmod, d, dmod, rgbmod\\+d"):
        build_model("resnet50")


def test_authors_file_without_variant_asks_for_it(tmp_path):
    path = save_authors_checkpoint(tmp_path / "r.pth", "rgbmod")
    with pytest.raises(CheckpointError, match="--variant"):
        model_from_checkpoint(path)


def test_our_checkpoint_carries_its_spec(tmp_path):
    spec = ModelSpec("dmod", width=0.25, input_scale=0.25)
    save_checkpoint(tmp_path / "ours.pth", build_model("dmod", 0.25), spec, {"trained_on": "synthetic"})
    model, got, ckpt = model_from_checkpoint(tmp_path / "ours.pth")
    assert got == spec and ckpt.meta["trained_on"] == "synthetic"


class _Evil:
    def __reduce__(self):
        return (os.system, ("echo pwned",))


@pytest.mark.parametrize("case", ["text", "empty", "truncated", "code_execution", "plain_pickle", "list"])
def test_bad_checkpoint_files_give_clear_errors(tmp_path, case):
    p = tmp_path / f"{case}.pth"
    if case == "text":
        p.write_text("this is a README, not weights\n")
        expect = "not a readable PyTorch checkpoint"
    elif case == "empty":
        p.write_bytes(b"")
        expect = "empty"
    elif case == "truncated":
        save_authors_checkpoint(p, "d")
        p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
        expect = "truncated"
    elif case == "code_execution":
        torch.save({"state_dict": random_state(authors_keys("d")), "hook": _Evil()}, p)
        expect = "needs code execution"
    elif case == "plain_pickle":
        p.write_bytes(pickle.dumps(_Evil()))
        expect = "needs code execution"
    else:
        torch.save([1, 2, 3], p)
        expect = "holds no state_dict"
    with pytest.raises(CheckpointError, match=expect) as err:
        load_checkpoint(p)
    assert str(p) in str(err.value)


def test_preprocess_matches_opencv_area_resize_and_colour_swap(aurova):
    frame = cv2.imread(str(aurova / "images" / "1508.png"))
    # the runtime's one reduction (edge/gate/reduce.py: two exact 2x2 box averages, OpenCV INTER_AREA), bit for bit
    half = cv2.resize(frame, (120, 160), interpolation=cv2.INTER_AREA)
    reduced = cv2.resize(half, (60, 80), interpolation=cv2.INTER_AREA)
    expected = cv2.cvtColor(reduced, cv2.COLOR_BGR2RGB).astype(np.float32) / 255.0
    got = Preprocess(0.25, "rgb")(torch.from_numpy(frame[None]))
    assert tuple(got.shape) == (1, 3, 80, 60)
    np.testing.assert_allclose(got[0].permute(1, 2, 0).numpy(), expected, atol=1e-6)
    exact = cv2.resize(cv2.cvtColor(frame, cv2.COLOR_BGR2RGB).astype(np.float32), (60, 80),
                       interpolation=cv2.INTER_AREA) / 255.0
    assert np.abs(got[0].permute(1, 2, 0).numpy() - exact).max() <= 1.0 / 255 + 1e-6  # within a grey level
    depth = cv2.imread(str(aurova / "filt_img_depth" / "depth_img_1508.png"), cv2.IMREAD_GRAYSCALE)
    d = Preprocess(1.0, "depth")(torch.from_numpy(depth[None, :, :, None]))
    np.testing.assert_allclose(d[0, 0].numpy(), depth / 255.0, atol=1e-7)


def test_unsupported_input_scale():
    from tactile_force.edge.errors import TactileForceError

    with pytest.raises(TactileForceError, match="input_scale 0.3"):
        Preprocess(0.3)


@pytest.mark.parametrize("variant", ["rgbmod", "d", "dmod", "rgbmod+d"])
def test_folded_head_equals_the_trained_head(variant):
    torch.manual_seed(0)
    model = build_model(variant, 0.25).eval()
    spec = ModelSpec(variant, 0.25, 0.25)
    frames = {"rgb": torch.randint(0, 256, (2, 320, 240, 3), dtype=torch.uint8),
              "depth": torch.randint(0, 256, (2, 320, 240, 1), dtype=torch.uint8)}
    a, b = ForceNet(model, spec), ForceNet(model, spec, folded=True)
    args = [frames[n] for n in a.input_names]
    with torch.no_grad():
        ya, yb = a(*args), b(*args)
    assert ya.shape == (2,)
    torch.testing.assert_close(yb, ya, atol=1e-5, rtol=1e-5)
