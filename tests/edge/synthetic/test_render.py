"""The virtual DIGIT renderer: force-monotonic, saturating, near-invisible below 1 N,
deterministic, physically consistent, and strict about bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from tactile_force.edge.synthetic import ContactSpec, VirtualDigit, VirtualDigitOptions, dome_height_mm
from tactile_force.edge.synthetic.mechanics import GelOptions, hertz_depth, penalty_depth

from tests.conftest import shared_data

QUIET = VirtualDigitOptions(noise_std_bgr=(0.0, 0.0, 0.0), seed=0)


@pytest.fixture(scope="module")
def quiet_digit() -> VirtualDigit:
    return VirtualDigit(QUIET)


def _change(digit: VirtualDigit, out) -> float:
    return float(np.abs(out.frame.astype(np.int16) - digit.background.astype(np.int16)).mean())


@pytest.mark.parametrize("indenter", ["circle_large", "star_small", "ball_2.35mm", "pen"])
def test_force_sweep_is_monotonic_and_saturates(quiet_digit, indenter):
    spec = ContactSpec(indenter, (150.0, 125.0), rotation_deg=17.0)
    forces = [0.5, 1.0, 2.0, 4.0, 6.0, 8.0, 10.0, 12.0, 15.0, 17.5, 20.0]
    outs = [quiet_digit.render(spec, f) for f in forces]
    area = np.array([o.contact_mask.sum() for o in outs])
    change = np.array([_change(quiet_digit, o) for o in outs])
    depth = np.array([o.height_mm.max() for o in outs])
    assert np.all(np.diff(area) >= 0), area
    assert np.all(np.diff(depth) > 0), depth
    assert np.all(np.diff(change) > -0.02), change  # uint8 rounding only
    i2, i10, i15, i20 = forces.index(2.0), forces.index(10.0), forces.index(15.0), forces.index(20.0)
    assert change[i10] > 1.5 * change[i2]
    # saturation: 15 -> 20 N adds far less deformation than 2 -> 10 N
    assert depth[i20] - depth[i15] < 0.25 * (depth[i10] - depth[i2])
    # below 1 N: the image change is under the real sensor's noise (about 2 grey levels)
    assert change[0] < 1.0 < change[i2]


def test_below_one_newton_is_near_noise_floor():
    noisy = VirtualDigit(VirtualDigitOptions(seed=3))
    spec = ContactSpec("square_large", (160.0, 120.0))
    rng = np.random.default_rng(0)
    empty = noisy.render(None, 0.0, rng=rng).frame.astype(np.float32)
    light = noisy.render(spec, 0.5, rng=rng).frame.astype(np.float32)
    firm = noisy.render(spec, 8.0, rng=rng).frame.astype(np.float32)
    floor = np.abs(empty - noisy.background).mean()
    assert np.abs(light - noisy.background).mean() < 1.3 * floor
    assert np.abs(firm - noisy.background).mean() > 2.0 * floor


def test_determinism_under_seed():
    spec = ContactSpec("hexagon_small", (140.0, 110.0), 33.0, "high")
    a = VirtualDigit(VirtualDigitOptions(seed=5)).render(spec, 7.0)
    b = VirtualDigit(VirtualDigitOptions(seed=5)).render(spec, 7.0)
    c = VirtualDigit(VirtualDigitOptions(seed=6)).render(spec, 7.0)
    assert np.array_equal(a.frame, b.frame) and a.meta == b.meta
    assert not np.array_equal(a.frame, c.frame)
    assert np.array_equal(a.contact_mask, c.contact_mask)  # noise differs, geometry does not


def test_output_contract(quiet_digit):
    out = quiet_digit.render(ContactSpec("cross_large", (160.0, 120.0), 45.0), 9.0, led_gain=(1.02, 0.98, 1.0))
    assert out.frame.shape == (320, 240, 3) and out.frame.dtype == np.uint8
    assert out.height_mm.shape == (320, 240) and out.height_mm.dtype == np.float32
    assert out.contact_mask.shape == (320, 240) and out.contact_mask.dtype == bool
    assert out.force_n == 9.0 and out.meta["contact_area_px"] == int(out.contact_mask.sum())
    for key in ("indenter", "shape", "scale", "size_mm", "stiffness", "location", "center_px", "rotation_deg",
                "force_n", "depth_mm", "led_gain"):
        assert key in out.meta
    # the deformation is largest where the body touches
    assert out.height_mm[out.contact_mask].mean() > 2 * out.height_mm[~out.contact_mask].mean()
    empty = quiet_digit.render(None, 0.0)
    assert not empty.contact_mask.any() and empty.height_mm.max() == 0.0


def test_hertz_ball_press_geometry(quiet_digit):
    r, d = 2.35, 0.4
    out = quiet_digit.render_ball_press((160.0, 120.0), r, d)
    ppm = quiet_digit.options.px_per_mm
    expected_area = math.pi * (2 * r * d - d * d) * ppm * ppm  # spherical cap footprint
    assert out.contact_mask.sum() == pytest.approx(expected_area, rel=0.1)
    assert out.height_mm.max() == pytest.approx(d, rel=0.02)
    # force of that depth is the Hertz force; rendering that force gives the same depth back
    e = quiet_digit.options.gel.gel_modulus_mpa
    assert hertz_depth(out.force_n, r, e) == pytest.approx(d, rel=1e-6)


def test_soft_objects_show_less(quiet_digit):
    deep = {s: quiet_digit.render(ContactSpec("sphere_4mm", (160.0, 120.0), stiffness=s), 6.0).height_mm.max()
            for s in ("medium", "high", "very_high")}
    assert deep["medium"] < deep["high"] < deep["very_high"]


def test_edge_contact_is_partial_and_labelled(quiet_digit):
    centre = quiet_digit.render(ContactSpec("circle_large", (160.0, 120.0)), 8.0)
    edge = quiet_digit.render(ContactSpec("circle_large", (160.0, 5.0)), 8.0)
    assert centre.meta["location"] == "center" and edge.meta["location"] == "edge"
    assert 0 < edge.contact_mask.sum() < 0.7 * centre.contact_mask.sum()


def test_penalty_model_matches_flat_punch_for_a_disc():
    ppm = 20.0
    yy, xx = np.mgrid[-100:101, -100:101] / ppm
    gap = np.where(np.hypot(xx, yy) <= 3.0, 0.0, np.inf)
    opts = GelOptions()
    d = penalty_depth(5.0, gap[np.isfinite(gap)], 1 / ppm ** 2, opts.gel_modulus_mpa, opts)
    assert d == pytest.approx(5.0 / (2 * 3.0 * opts.gel_modulus_mpa), rel=0.02)


@pytest.mark.parametrize("force", [-1.0, float("nan"), float("inf")])
def test_bad_force_is_rejected(quiet_digit, force):
    with pytest.raises(ValueError, match="force_n"):
        quiet_digit.render(ContactSpec("circle_small"), force)


def test_bad_names_are_rejected(quiet_digit):
    with pytest.raises(ValueError, match="unknown indenter 'teapot'"):
        quiet_digit.render(ContactSpec("teapot"), 2.0)
    with pytest.raises(ValueError, match="stiffness 'rubbery'"):
        quiet_digit.render(ContactSpec("circle_small", stiffness="rubbery"), 2.0)


def test_bad_background_is_rejected(tmp_path):
    bad = tmp_path / "bg.png"
    bad.write_bytes(b"not a png")
    with pytest.raises(Exception, match="bg.png"):
        VirtualDigit(VirtualDigitOptions(background=bad))


def test_parametric_dome_matches_the_real_pad():
    real = np.load(shared_data("fots_digit", "digit_pad_mm.npy"))
    ours = dome_height_mm(real.shape)
    assert np.abs(ours - real).max() < 0.12
    assert np.abs(ours - real).mean() < 0.04


def test_fots_mlp_shading_option():
    mlp = shared_data("fots_digit", "mlp_normal_to_rgb.npz")
    digit = VirtualDigit(VirtualDigitOptions(normal_to_rgb_mlp=mlp, noise_std_bgr=(0, 0, 0)))
    weak = _change(digit, digit.render_ball_press((160.0, 120.0), 2.35, 0.2))
    strong = _change(digit, digit.render_ball_press((160.0, 120.0), 2.35, 0.8))
    assert 0.2 < weak < strong


def test_bad_mlp_file_names_it(tmp_path):
    bad = tmp_path / "mlp.npz"
    np.savez(bad, fc1_weight=np.zeros((3, 3)))
    with pytest.raises(Exception, match="mlp.npz"):
        VirtualDigit(VirtualDigitOptions(normal_to_rgb_mlp=bad))
