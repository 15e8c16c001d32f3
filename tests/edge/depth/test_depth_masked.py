"""Depth where the contact is: the colour->normal mapping evaluated only inside the (dilated)
contact mask gives, inside the mask, exactly what evaluating every pixel gives; the fast
form of the paper MLP is the authors' four layers; mapping_step 2 copies each 2x2 cell's
evaluated pixel. Real AUROVA frames and the real paper MLP."""

import cv2
import numpy as np
import pytest
from tactile_force.edge.depth import DepthOptions, DepthStage
from tactile_force.edge.depth.gradients import normals_to_gradients
from tactile_force.edge.depth.normals import PaperMLP, decode_paper_normals
from tactile_force.edge.depth.poisson import PoissonSolver

from tests.conftest import shared_data


def frame(n: int) -> np.ndarray:
    return cv2.imread(str(shared_data("aurova_digit_grasp", "images", f"{n}.png")))


def contact_mask(n: int) -> np.ndarray:
    """The authors' contact region of frame n (their filtered depth image > 0), bool 320x240."""
    d = cv2.imread(str(shared_data("aurova_digit_grasp", "filt_img_depth", f"depth_img_{n}.png")), cv2.IMREAD_GRAYSCALE)
    return d > 0


def full_gradients(mlp: PaperMLP, f: np.ndarray, opts: DepthOptions) -> tuple[np.ndarray, np.ndarray]:
    """Exact-mode gradients with the MLP run on EVERY pixel, the authors' layer by layer."""
    n = decode_paper_normals(mlp.encoded_reference(f))
    gx, gy, _ = normals_to_gradients(n, opts.guards)
    return gx.reshape(320, 240).astype(np.float32), gy.reshape(320, 240).astype(np.float32)


def test_fast_mlp_is_the_four_layers_and_pixels_are_independent(paper_mlp_path):
    mlp = PaperMLP.load(paper_mlp_path)
    f = frame(1512)
    fast, ref = mlp.encoded(f), mlp.encoded_reference(f)
    assert fast.shape == ref.shape == (320 * 240, 3)
    np.testing.assert_allclose(fast, ref, atol=1e-5)
    idx = np.flatnonzero(contact_mask(1512))
    assert idx.size > 1000
    np.testing.assert_allclose(mlp.encoded(f, idx), fast[idx], atol=1e-6)


@pytest.mark.parametrize("n", [1508, 1516])
def test_exact_mode_masked_equals_full_evaluation_inside_the_mask(paper_mlp_path, n):
    opts = DepthOptions(paper_mlp_path)
    st = DepthStage(opts)
    f, m = frame(n), contact_mask(n)
    res = st.process(f, m)
    assert res.ok and res.contact_px == int(m.sum())
    gx, gy = full_gradients(st.mlp, f, opts)
    gx[~m] = 0.0  # exact mode: no slope outside the contact
    gy[~m] = 0.0
    solver = PoissonSolver((320, 240), np.float32)
    h = solver.solve(gx, gy, out=np.zeros((320, 240), np.float32))
    np.testing.assert_allclose(res.height, h, atol=1e-4 * max(1.0, float(np.abs(h).max())))
    scaled = np.clip(np.rint(np.clip(h * opts.levels_per_px, 0, 255)), 0, 255)
    scaled[~m] = 0
    assert np.abs(res.depth[..., 0].astype(int) - scaled.astype(int)).max() <= 1  # rounding at a .5 only
    assert res.depth[~m].max() == 0


def test_mapping_step_two_copies_the_even_pixel_of_each_cell(paper_mlp_path):
    opts = DepthOptions(paper_mlp_path, mapping_step=2)
    st = DepthStage(opts)
    f, m = frame(1512), contact_mask(1512)
    res = st.process(f, m)
    assert res.ok
    gx, _ = full_gradients(st.mlp, f, opts)
    rows, cols = np.nonzero(m)
    np.testing.assert_allclose(st._gx[rows, cols], gx[rows // 2 * 2, cols // 2 * 2], atol=1e-5)
    with pytest.raises(ValueError, match="mapping_step"):
        DepthOptions(paper_mlp_path, mapping_step=3)


def test_paper_mode_evaluates_the_dilated_mask_and_keeps_the_reference_outside(paper_mlp_path):
    f, m = frame(1516), contact_mask(1516)
    masked = DepthStage(DepthOptions(paper_mlp_path, mode="paper", paper_dilation_px=16))
    full = DepthStage(DepthOptions(paper_mlp_path, mode="paper", paper_dilation_px=None))
    for st in (masked, full):
        st.set_reference([frame(1500)])
    a, b = masked.process(f, m), full.process(f, m)
    assert a.ok and b.ok
    idx = masked.paper_index(m)
    inside = np.zeros(320 * 240, bool)
    inside[idx] = True
    inside = inside.reshape(320, 240)
    assert inside[m].all() and inside.sum() > m.sum()  # the dilated mask holds the contact and more
    # Inside the dilated mask the gradients are the full evaluation's; outside, the reference's.
    np.testing.assert_allclose(masked._gx[inside], full._gx[inside], atol=1e-7)
    np.testing.assert_allclose(masked._gx[~inside], masked._ref_gx[~inside])
    # The depth images differ only through what lies outside the dilated mask.
    diff = np.abs(a.depth[..., 0].astype(int) - b.depth[..., 0].astype(int))
    assert diff[~m].max() == 0 and diff[m].mean() < 0.1 * max(1.0, float(b.depth[m].mean()))
    with pytest.raises(ValueError, match="paper_dilation_px"):
        DepthOptions(paper_mlp_path, mode="paper", paper_dilation_px=-1)


def test_lut_gradients_in_the_mask_box_equal_full_evaluation_inside_the_mask(fots_lut_path):
    """The LUT path works on the mask's bounding box; inside the mask it gives what
    evaluating every pixel gives, zero outside (exact mode)."""
    st = DepthStage(DepthOptions(fots_lut_path))
    img = cv2.imread(str(shared_data("fots_digit", "ball_presses", "0040.png")))
    frame320 = cv2.resize(img, (240, 320), interpolation=cv2.INTER_AREA) if img.shape[:2] != (320, 240) else img
    m = np.zeros((320, 240), bool)
    cv2.circle(m.view(np.uint8), (130, 150), 45, 1, -1)
    m[10:20, 200:230] = True  # a second blob: the box spans both
    res = st.process(frame320, m)
    assert res.ok
    full = st._glut[st.lut.index(frame320)]  # every pixel
    gx = full[:, 0].reshape(320, 240)
    np.testing.assert_array_equal(st._gx[m], gx[m])
    assert not st._gx[~m].any() and not st._gy[~m].any()
