"""Depth at the network resolution: colour -> normal and the exact DST-I
solve on the frame reduced to the network input (80 x 60 for 1/4), heights in full-resolution
pixels (DepthOptions, Notes).

Tolerances (stated here, measured when written):

* the grid solve of a height map's own discrete gradients returns it to 1e-9 px (float64);
* a spherical cap's analytic slope field, sampled at the 80 x 60 block centres and integrated
  with the stage's midpoint rule, is within 0.5 px of the analytic cap (peak 10.7 px, rim
  radius 40 px; the kink at the rim is what is left) and within 0.4 px of the full-resolution
  solve reduced by 4 x 4 block means;
* the whole stage on a virtual-DIGIT ball press: the same depth from the full frame + full mask
  as from the reduced frame + the gate's reduced mask, and within 3 grey levels (mean) of the
  full-resolution depth image reduced to 80 x 60.
"""

import numpy as np
import pytest
from tactile_force.edge.bundle.manifest import DepthRecord, FrameReduction, Reduction
from tactile_force.edge.depth import DepthOptions, DepthStage
from tactile_force.edge.depth.poisson import PoissonSolver, forward_gradients
from tactile_force.edge.depth.stage import _midpoint_slopes

H, W, K = 320, 240, 4
MAPPING = "edge/assets/virtual_digit_depth.npz"


def cap_field(rows, cols, cy=160.0, cx=120.0, rc=40.0, radius=80.0):
    """Spherical cap of a ball of ``radius`` px cut at rim radius ``rc`` px (full-resolution
    pixels): height and its analytic slopes dh/dcol, dh/drow."""
    r2 = (rows - cy) ** 2 + (cols - cx) ** 2
    inside = r2 < rc * rc
    z = np.sqrt(np.maximum(radius * radius - r2, 1e-12))
    h = np.where(inside, z - np.sqrt(radius * radius - rc * rc), 0.0)
    return h, np.where(inside, -(cols - cx) / z, 0.0), np.where(inside, -(rows - cy) / z, 0.0)


def grid_centres(k=K):
    r, c = np.mgrid[0:H // k, 0:W // k].astype(np.float64)
    return r * k + (k - 1) / 2.0, c * k + (k - 1) / 2.0


def test_grid_solve_is_exact_on_its_own_discrete_gradients():
    rows, cols = grid_centres()
    h, _, _ = cap_field(rows, cols)
    gx, gy = forward_gradients(h)
    out = PoissonSolver((H // K, W // K), np.float64).solve(gx, gy)
    assert out.shape == (80, 60)
    assert np.abs(out - h).max() < 1e-9


def test_analytic_sphere_at_80x60_matches_exact_cap_and_full_resolution_solve():
    rows, cols = grid_centres()
    h, sx, sy = cap_field(rows, cols)
    gx, gy = K * sx, K * sy  # height (full-resolution px) per grid pixel
    _midpoint_slopes(gx, gy)
    grid = PoissonSolver((H // K, W // K), np.float64).solve(gx, gy)
    assert abs(grid.max() - h.max()) < 0.2
    assert np.abs(grid - h).max() < 0.5

    r0, c0 = np.mgrid[0:H, 0:W].astype(np.float64)
    _, fx, fy = cap_field(r0, c0)
    _midpoint_slopes(fx, fy)
    full = PoissonSolver((H, W), np.float64).solve(fx, fy)
    reduced = full.reshape(H // K, K, W // K, K).mean(axis=(1, 3))
    assert np.abs(grid - reduced).max() < 0.4


def test_midpoint_rule_beats_the_pixels_own_slope_at_a_coarse_grid():
    """What the convention buys: the pixel's own slope as a forward difference shifts the
    surface by half a grid pixel (error 3x larger on the same cap)."""
    rows, cols = grid_centres()
    h, sx, sy = cap_field(rows, cols)
    solver = PoissonSolver((H // K, W // K), np.float64)
    own = solver.solve(K * sx, K * sy)
    gx, gy = K * sx, K * sy
    _midpoint_slopes(gx, gy)
    mid = solver.solve(gx, gy)
    assert np.abs(own - h).max() > 2.5 * np.abs(mid - h).max()


@pytest.fixture(scope="module")
def press():
    from tactile_force.edge import ContactGate
    from tactile_force.edge.synthetic import VirtualDigit, VirtualDigitOptions

    digit = VirtualDigit(VirtualDigitOptions())
    bg = digit.render(None, 0.0, led_gain=(1.0, 1.0, 1.0)).frame
    shot = digit.render_ball_press((150.0, 110.0), 4.0, 0.8, led_gain=(1.0, 1.0, 1.0), rng=np.random.default_rng(3))
    gate = ContactGate()
    gate.capture_background([bg])
    g = gate.update(shot.frame)
    assert g.contact
    return shot.frame, g.mask.copy()


def test_stage_at_network_resolution_reads_full_or_reduced_input_alike(press):
    from tactile_force.edge.gate.reduce import default_reduction, reduce_frames

    frame, mask = press
    stage = DepthStage(DepthOptions(mapping=MAPPING, levels_per_px=255 / 48, downscale=4))
    assert stage.output_shape == (80, 60, 1)
    a = stage.process(frame, mask)
    small = reduce_frames(frame[None], default_reduction(4))[0]
    small_mask = mask[::4, ::4]  # the gate's mask is its 80x60 mask upscaled by nearest
    b = stage.process(small, small_mask)
    assert a.ok and b.ok, (a.detail, b.detail)
    assert a.depth.shape == (80, 60, 1) and a.depth.max() > 100
    np.testing.assert_array_equal(a.depth, b.depth)


def test_stage_at_network_resolution_close_to_full_resolution_reduced(press):
    frame, mask = press
    full = DepthStage(DepthOptions(mapping=MAPPING, levels_per_px=255 / 48)).process(frame, mask)
    grid = DepthStage(DepthOptions(mapping=MAPPING, levels_per_px=255 / 48, downscale=4)).process(frame, mask)
    reduced = full.depth[..., 0].reshape(80, 4, 60, 4).astype(np.float64).mean(axis=(1, 3))
    diff = np.abs(grid.depth[..., 0].astype(np.float64) - reduced)
    inside = mask[::4, ::4] > 0
    assert diff[inside].mean() < 3.0
    assert abs(float(grid.height.max()) - float(full.height.max())) < 0.05 * float(full.height.max())


def test_checked_skips_only_the_repeated_frame_checks(press):
    """``checked=True`` (the runtime: it judged the reduced image's exposure) gives the same depth
    as the unchecked call, and a frame that is not a grid image is still checked."""
    from tactile_force.edge.gate.reduce import default_reduction, reduce_frames

    frame, mask = press
    stage = DepthStage(DepthOptions(mapping=MAPPING, levels_per_px=255 / 48, downscale=4))
    small = reduce_frames(frame[None], default_reduction(4))[0]
    a = stage.process(small, mask[::4, ::4])
    b = stage.process(small, np.ascontiguousarray(mask[::4, ::4]), checked=True)
    assert a.ok and b.ok and a.contact_px == b.contact_px
    np.testing.assert_array_equal(a.depth, b.depth)
    bad = stage.process(small.astype(np.float32), mask[::4, ::4], checked=True)  # not what checked vouches for
    assert not bad.ok and "uint8" in bad.detail
    dark = stage.process(np.zeros_like(small), mask[::4, ::4])
    assert not dark.ok and "all-dark" in dark.detail


def test_bad_shapes_named_not_raised(press):
    frame, mask = press
    stage = DepthStage(DepthOptions(mapping=MAPPING, downscale=4))
    r = stage.process(frame[:100], mask)
    assert not r.ok and "(80, 60, 3)" in r.detail and r.depth.shape == (80, 60, 1)
    r = stage.process(frame, mask[:50])
    assert not r.ok and "(80, 60)" in r.detail


@pytest.mark.parametrize("kwargs, match", [
    ({"downscale": 3}, "dividing 320 and 240"),
    ({"downscale": 4, "mode": "paper"}, "paper mode runs at full resolution"),
    ({"downscale": 4, "mapping_step": 2}, "mapping_step=1"),
    ({"downscale": 4, "reduction": "bilinear"}, "reduction"),
    ({"downscale": 5, "reduction": "area-2x-steps"}, "power-of-two"),
])
def test_options_refuse_what_cannot_be_made(kwargs, match):
    with pytest.raises(ValueError, match=match):
        DepthOptions(mapping=MAPPING, **kwargs)


def test_depth_record_carries_the_grid_and_old_records_mean_full_resolution():
    from tactile_force.edge.typed_json import from_json, to_json

    old = from_json(DepthRecord, {"mapping": "package:virtual_digit_depth.npz", "mode": "exact"})
    assert old.downscale == 1 and old.grid_hw == (320, 240)
    rec = DepthRecord("package:virtual_digit_depth.npz", reduction=FrameReduction(Reduction.AREA_2X_STEPS, 4))
    back = from_json(DepthRecord, to_json(rec))
    assert back == rec and back.grid_hw == (80, 60)
    back.check()
    with pytest.raises(ValueError, match="paper mode"):
        DepthRecord("x.npz", mode="paper", reduction=FrameReduction(Reduction.AREA, 4)).check()


def test_runtime_builds_the_recorded_grid():
    from tactile_force.edge.bundle.manifest import InputKind, InputSpec, Manifest
    from tactile_force.edge.runtime import build_depth_stage

    red = FrameReduction(Reduction.AREA_2X_STEPS, 4)
    m = Manifest("d", "fp32", [InputSpec("depth", InputKind.DEPTH, [-1, 80, 60, 1], colour_order="GRAY",
                                         reduction=red)],
                 depth=DepthRecord("package:virtual_digit_depth.npz", levels_per_px=255 / 48, reduction=red))
    stage = build_depth_stage(None, m)
    assert stage.options.downscale == 4 and stage.options.reduction == "area-2x-steps"
    assert stage.output_shape == (80, 60, 1)


@pytest.mark.parametrize("shape", [(80, 60), (40, 30), (320, 240)])
def test_matmul_backend_is_the_same_transform(shape):
    """The dense sine-matrix DST-I ('auto' on small grids) solves exactly like scipy's FFT."""
    rng = np.random.default_rng(0)
    gx, gy = rng.normal(size=shape), rng.normal(size=shape)
    a = PoissonSolver(shape, np.float64, "matmul").solve(gx, gy)
    b = PoissonSolver(shape, np.float64, "scipy").solve(gx, gy)
    assert np.abs(a - b).max() < 1e-9 * max(1.0, np.abs(b).max())
    assert PoissonSolver((80, 60)).backend == "matmul" and PoissonSolver((320, 240)).backend == "scipy"
    rows, cols = grid_centres()
    h, _, _ = cap_field(rows, cols)
    out = PoissonSolver((80, 60), np.float32).solve(*(g.astype(np.float32) for g in forward_gradients(h)))
    assert np.abs(out - h).max() < 2e-5 * h.max()


def test_paper_mlp_on_the_grid_reads_block_centre_positions(paper_mlp_path):
    """Exact mode with the paper MLP at downscale 4: its position inputs are the 4 x 4 blocks'
    centres in full-resolution pixels (normalised by 240 / 320 as the authors did)."""
    stage = DepthStage(DepthOptions(mapping=paper_mlp_path, downscale=4))
    mlp = stage.mlp
    assert mlp is not None and mlp.pitch == 4
    mlp.encoded(np.zeros((80, 60, 3), np.uint8), np.arange(1))
    xy = mlp._xy.reshape(80, 60, 2)
    assert np.allclose(xy[0, 0], (1.5 / 240, 1.5 / 320)) and np.allclose(xy[79, 59], (237.5 / 240, 317.5 / 320))
