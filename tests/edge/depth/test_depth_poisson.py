"""Exact DST-I Poisson solve: analytic shapes from their discrete gradients, to float precision."""

import numpy as np
import pytest
from tactile_force.edge.depth.poisson import PoissonSolver, forward_gradients

H, W = 320, 240
ROWS, COLS = np.mgrid[0:H, 0:W].astype(np.float64)


def cap(cy, cx, rc, R):
    r = np.hypot(ROWS - cy, COLS - cx)
    return np.where(r < rc, np.sqrt(np.maximum(R * R - r * r, 0)) - np.sqrt(R * R - rc * rc), 0.0)


SHAPES = {
    "spherical cap": cap(150, 110, 30, 60),
    "20 px cap": cap(160, 120, 20, 40),
    "cylinder": np.where(np.abs(COLS - 120) < 25, np.sqrt(np.maximum(40.0**2 - (COLS - 120) ** 2, 0)) - np.sqrt(40.0**2 - 25**2), 0.0)
    * ((ROWS > 60) & (ROWS < 260)),
    "ramp (tent)": np.maximum(0.0, 12.0 - 0.4 * np.abs(COLS - 120) - 0.1 * np.abs(ROWS - 160)),
    # rim tangent to row 0 / column 0, and one reaching the virtual row H (bottom border)
    "cap touching top-left border": cap(30, 30, 30, 50),
    "cap touching bottom border": cap(H - 20, 100, 20, 35),
}


@pytest.mark.parametrize("name", list(SHAPES))
@pytest.mark.parametrize("backend", ["scipy", "numpy"])
def test_exact_reconstruction_float64(name, backend):
    h = SHAPES[name]
    gx, gy = forward_gradients(h)
    out = PoissonSolver((H, W), np.float64, backend).solve(gx, gy)
    assert np.abs(out - h).max() < 1e-9 * max(1.0, h.max())


@pytest.mark.parametrize("name", ["spherical cap", "cylinder", "ramp (tent)"])
def test_exact_reconstruction_float32(name):
    h = SHAPES[name]
    gx, gy = forward_gradients(h.astype(np.float32))
    out = PoissonSolver((H, W), np.float32).solve(gx, gy)
    assert np.abs(out - h).max() < 2e-5 * h.max()


def test_buffers_reused_and_shape_checked():
    s = PoissonSolver((H, W))
    gx, gy = forward_gradients(SHAPES["spherical cap"].astype(np.float32))
    out = np.full((H, W), 7.0, np.float32)
    res = s.solve(gx, gy, out=out)
    assert res is out and out[0, 0] == 0.0
    with pytest.raises(ValueError, match="expected"):
        s.solve(gx[:10], gy)
    with pytest.raises(ValueError, match="dtype"):
        PoissonSolver((H, W), np.int32)


def test_dst2_port_overshoots_where_exact_does_not():
    """The digit-depth/PyTouch port (DST-II, pi k/(n+2)) overshoots a 20 px cap."""
    from tests.edge.depth.poisson_port import port_solve

    h = SHAPES["20 px cap"]
    gx, gy = forward_gradients(h)
    port = port_solve(gx, gy)
    over = port.max() / h.max() - 1.0
    assert over > 0.005
    assert abs(PoissonSolver((H, W), np.float64).solve(gx, gy).max() / h.max() - 1.0) < 1e-9
