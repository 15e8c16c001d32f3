"""The Poisson solve's DST-I by even and odd halves (edge/depth/sine_halves.py): the transform of the
dense sine matrices to float rounding, and readings of the shipped depth bundles that move by no more
than rounding: every force within 1e-4 N of the dense products' and every flag, contact decision and
interval state the same, over virtual grasps and every real DIGIT recording of the shared data."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from tactile_force.edge.depth.poisson import PoissonSolver, _eigenvalues
from tactile_force.edge.depth.sine_halves import SineHalves, sine_matrix

from tests.conftest import ListSource, shared_data

SHAPES = [(1, 1), (1, 2), (2, 1), (2, 3), (3, 2), (4, 5), (8, 8), (39, 29), (79, 59), (80, 60)]


@pytest.mark.parametrize("shape", SHAPES)
def test_halves_are_the_dense_transform(shape):
    rows, cols = shape
    rng = np.random.default_rng(rows * 100 + cols)
    x = rng.normal(size=shape)
    dense = sine_matrix(rows) @ x @ sine_matrix(cols)
    h = SineHalves(rows, cols, np.float64)
    spec = h.forward(x)
    scale = np.abs(dense).max()
    assert np.abs(spec - h.split(dense)).max() <= 1e-12 * scale
    back = h.inverse(h.split(dense).copy())
    want = sine_matrix(rows) @ dense @ sine_matrix(cols)
    assert np.abs(back - want).max() <= 1e-12 * np.abs(want).max()
    # DST-I applied twice is 2(n+1) times the identity, per axis
    np.testing.assert_allclose(h.inverse(spec.copy()), x * (2 * (rows + 1)) * (2 * (cols + 1)), atol=1e-9 * scale)


def test_split_order_is_even_then_odd():
    h = SineHalves(5, 4, np.float64)
    t = np.arange(20.0).reshape(5, 4)
    s = h.split(t)
    assert s[:, 0].tolist() == [0.0, 8.0, 16.0, 4.0, 12.0] and s[0].tolist() == [0.0, 2.0, 1.0, 3.0]


def _dense_solve(solver: PoissonSolver, d: np.ndarray) -> np.ndarray:
    """The solve as the dense products made it (float32 S_r @ d @ S_c, the eigenvalues, again)."""
    n_r, n_c = d.shape
    lam = _eigenvalues(n_r, np.float64)[:, None] + _eigenvalues(n_c, np.float64)[None, :]
    inv = (1.0 / (lam * (2.0 * (n_r + 1)) * (2.0 * (n_c + 1)))).astype(solver.dtype)
    s_r, s_c = sine_matrix(n_r).astype(solver.dtype), sine_matrix(n_c).astype(solver.dtype)
    spec = (s_r @ d) @ s_c
    spec *= inv
    return (s_r @ spec) @ s_c


@pytest.mark.parametrize("shape", [(80, 60), (40, 30)])
def test_float32_solve_equals_the_dense_products_to_rounding(shape):
    rng = np.random.default_rng(1)
    solver = PoissonSolver(shape, np.float32)
    assert solver.backend == "matmul"
    for _ in range(5):
        d = rng.normal(size=(shape[0] - 1, shape[1] - 1)).astype(np.float32)
        want = _dense_solve(solver, d)
        got = solver.solve_divergence(d.copy())
        assert np.abs(got - want).max() <= 1e-5 * np.abs(want).max()


# -- readings ---------------------------------------------------------------------------------
def _digit(path) -> np.ndarray:
    img = cv2.imread(str(path))
    assert img is not None, path
    return img


def _recordings() -> dict[str, tuple[list[np.ndarray], list[np.ndarray]]]:
    """Every real DIGIT recording of the shared data: (background frames, frames)."""
    bg = shared_data("digit_backgrounds")
    out = {}
    for name in ("aurova_digit_grasp", "aurova_digit_grasp_heldout"):
        images = sorted(shared_data(name, "images").glob("*.png"), key=lambda p: int(p.stem))
        out[name] = ([_digit(bg / "aurova_background_b.png")], [_digit(p) for p in images])
    presses = sorted(shared_data("fots_digit", "ball_presses").glob("*.png"))
    out["fots_digit ball presses"] = ([_digit(bg / "fots_digit_bg.png")], [_digit(p) for p in presses])
    return out


def _readings(bundle, background, frames) -> list[tuple]:
    from tactile_force.edge import ContactGate
    from tactile_force.edge.model.onnx_model import OnnxForceModel
    from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor

    gate = ContactGate()
    if background:
        gate.capture_background(background)
    model = OnnxForceModel(bundle, threads=1)
    rt = ForceRuntime([Sensor("s", ListSource(frames), gate)], model, RuntimeOptions(deadline_ms=1e6, prewarm=False))
    out = []
    try:
        while not rt.finished:
            out += [(r.frame_index, r.force_n, r.raw_force_n, r.force_low_n, r.force_high_n, int(r.flags),
                     r.interval.value, r.contact_area_px, r.detail) for r in rt.step()]
    finally:
        rt.close()
    return out


def _same_but_rounding(got: list[tuple], want: list[tuple], where: str) -> float:
    """Every field equal but the forces, which may differ by 1e-4 N; returns the largest difference."""
    assert len(got) == len(want), where
    worst = 0.0
    for g, w in zip(got, want):
        assert (g[0], *g[5:]) == (w[0], *w[5:]), f"{where}: frame {g[0]}: {g} != {w}"
        for a, b in zip(g[1:5], w[1:5]):
            assert np.isnan(a) == np.isnan(b), f"{where}: frame {g[0]}: {g} != {w}"
            if not np.isnan(a):
                worst = max(worst, abs(a - b))
    assert worst <= 1e-4, f"{where}: a force moved by {worst:.2e} N"
    return worst


@pytest.fixture(scope="module")
def depth_bundles():
    from tactile_force.edge.scene import shipped_bundles

    found = {k: v for k, v in shipped_bundles().items() if k in ("d", "rgbmod_d")}
    if not found:
        pytest.skip("no shipped depth bundle in edge/models")
    return found


def _virtual_frames(n_grasps: int = 3) -> list[np.ndarray]:
    from tactile_force.edge.synthetic.source import VirtualDigitSource

    src = VirtualDigitSource(seed=3, n_grasps=n_grasps, render_ahead=0)
    frames = []
    while (tf := src.read()) is not None:
        frames.append(tf.frame)
    src.close()
    return frames


def test_depth_readings_move_by_rounding_only(depth_bundles, monkeypatch):
    cases = {"virtual grasps": ([], _virtual_frames()), **_recordings()}
    with monkeypatch.context() as m:
        m.setattr(PoissonSolver, "solve_divergence", _dense_solve)
        want = {(b, c): _readings(p, *cases[c]) for b, p in depth_bundles.items() for c in cases}
    for (b, c), w in want.items():
        got = _readings(depth_bundles[b], *cases[c])
        assert any(r[7] > 0 for r in got) or c == "virtual grasps", f"{b} on {c}: no contact read"
        _same_but_rounding(got, w, f"{b} on {c}")
