import numpy as np
from tactile_force.edge.depth.gradients import GradientGuards, normals_to_gradients


def test_sign_convention_on_sphere():
    # Right of a ball's centre the normal tilts +x, so the indentation height falls: h_x < 0.
    n = np.array([[0.6, 0.0, 0.8], [0.0, -0.6, 0.8]], np.float32)
    gx, gy, bad = normals_to_gradients(n)
    assert gx[0] == np.float32(-0.75) and gy[0] == 0 and gy[1] == np.float32(0.75) and bad == 0


def test_guards_nz_to_zero_nan_and_clamp():
    n = np.array([[1.0, 0.0, 0.0], [0.7, 0.7, 1e-9], [np.nan, 0.0, 1.0], [0.0, np.inf, 1.0], [0.0, 0.0, -1.0]], np.float32)
    gx, gy, bad = normals_to_gradients(n, GradientGuards(nz_min=0.1, max_slope=4.0))
    assert np.all(np.isfinite(gx)) and np.all(np.isfinite(gy))
    assert np.abs(gx).max() <= 4.0 and np.abs(gy).max() <= 4.0
    assert gx[2] == 0 and bad >= 4
