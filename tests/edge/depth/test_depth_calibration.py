"""calibrate-depth on real ball presses: circle detection, held-out angle error, cap depth."""

import numpy as np
import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.depth import NormalLUT, PoissonSolver, normals_to_gradients
from tactile_force.edge.depth.calibration import (
    Circle,
    Press,
    cap_depth_px,
    detect_press_circle,
    evaluate_lut,
    fit_lut,
    sphere_normals,
)

from tests.conftest import shared_data

MM_PER_PX = 0.0295  # GelSight Mini (Taxim calibration data)
BALL_MM = 2.0  # Taxim's calibration ball radius


@pytest.fixture(scope="module")
def gelsight():
    z = np.load(shared_data("gelsight_mini_ball_presses.npz"))
    presses = [Press(z["imgs"][i], Circle(float(c[0]), float(c[1]), float(r)), str(i))
               for i, (c, r) in enumerate(zip(z["touch_center"], z["touch_radius"]))]
    return z["f0"], presses


def test_detected_circles_match_labels(gelsight):
    bg, presses = gelsight
    errs = []
    for p in presses:
        c = detect_press_circle(p.frame, bg)
        assert c is not None
        errs.append((np.hypot(c.cx - p.circle.cx, c.cy - p.circle.cy), abs(c.r - p.circle.r)))
    e = np.array(errs)
    assert np.median(e[:, 0]) < 12 and np.median(e[:, 1]) < 8, e
    assert detect_press_circle(bg, bg) is None


def test_heldout_angle_error_and_cap_depth(gelsight):
    bg, presses = gelsight
    R = BALL_MM / MM_PER_PX
    train = [p for i, p in enumerate(presses) if i % 4 != 1]
    test = [p for i, p in enumerate(presses) if i % 4 == 1]
    lut = fit_lut(train, bg, R)
    err = evaluate_lut(lut, test, R)
    assert err.pixels > 10000 and err.mean_deg < 10.0, err
    solver = PoissonSolver(bg.shape[:2], np.float64)
    ratios = []
    for p in test:
        _, inside, _ = sphere_normals(bg.shape[:2], p.circle, R)
        idx = np.flatnonzero(inside)
        gx = np.zeros(bg.shape[:2])
        gy = np.zeros(bg.shape[:2])
        vx, vy, _ = normals_to_gradients(lut.normals(p.frame, idx))
        gx.ravel()[idx] = vx
        gy.ravel()[idx] = vy
        ratios.append(solver.solve(gx, gy).max() / cap_depth_px(p.circle.r, R))
    assert all(0.7 < r < 1.3 for r in ratios), ratios


def test_cli_writes_a_loadable_calibration(tmp_path, capsys):
    out = tmp_path / "gs.npz"
    rc = cli_main(["calibrate-depth", str(shared_data("gelsight_mini_ball_presses.npz")), "--ball-radius-mm", "2.0",
                   "--px-per-mm", str(1 / MM_PER_PX), "-o", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "held-out" in text
    lut = NormalLUT.load(out)
    assert lut.report["test_presses"] == 4 and lut.report["heldout_angle_deg"]["mean"] < 12
    assert lut.background.shape == (480, 640, 3)


def test_cli_reports_missing_background(tmp_path, capsys):
    rc = cli_main(["calibrate-depth", str(shared_data("fots_digit", "ball_presses")), "--ball-radius-mm", "2.35",
                   "--px-per-mm", "19.58", "-o", str(tmp_path / "x.npz")])
    assert rc == 2 and "background" in capsys.readouterr().err  # bad input: exit 2


def test_cli_writes_the_circle_image(tmp_path, capsys):
    """The image next to the output shows every press with its circle where it was found."""
    import cv2
    from tactile_force.edge.cli.calibrate_depth import load_presses

    src = shared_data("gelsight_mini_ball_presses.npz")
    out = tmp_path / "cal" / "gs.npz"
    rc = cli_main(["calibrate-depth", str(src), "--ball-radius-mm", "2.0", "--px-per-mm", str(1 / MM_PER_PX),
                   "--detect", "-o", str(out)])
    assert rc == 0
    img_path = tmp_path / "cal" / "gs_circles.png"
    assert str(img_path) in capsys.readouterr().out
    img = cv2.imread(str(img_path))
    presses, bg = load_presses(str(src), None)
    cols = min(6, len(presses))
    rows = -(-len(presses) // cols)
    tile_h = round(bg.shape[0] * 240 / bg.shape[1])
    assert img.shape == (rows * (tile_h + 4) - 4, cols * (240 + 4) - 4, 3)
    # the first press's circle is drawn in green (fit) or orange (held out) on its ring
    c = detect_press_circle(presses[0].frame, bg)
    s = 240 / bg.shape[1]
    ring = [img[round(c.cy * s + c.r * s * np.sin(a)), round(c.cx * s + c.r * s * np.cos(a))]
            for a in np.linspace(0, 2 * np.pi, 16, endpoint=False)]
    green_or_orange = [(p[1] > 120 and p[2] < 80) or (p[2] > 200 and 100 < p[1] < 180 and p[0] < 60) for p in ring]
    assert sum(green_or_orange) >= 12, ring


def test_cli_overlay_path_and_bad_suffix(tmp_path, capsys):
    src = str(shared_data("gelsight_mini_ball_presses.npz"))
    over = tmp_path / "check" / "circles.jpg"
    rc = cli_main(["calibrate-depth", src, "--ball-radius-mm", "2.0", "--px-per-mm", str(1 / MM_PER_PX),
                   "-o", str(tmp_path / "x.npz"), "--overlay", str(over)])
    assert rc == 0 and over.is_file() and not (tmp_path / "x_circles.png").exists()
    rc = cli_main(["calibrate-depth", src, "--ball-radius-mm", "2.0", "--px-per-mm", str(1 / MM_PER_PX),
                   "-o", str(tmp_path / "y.npz"), "--overlay", str(tmp_path / "c.gif")])
    assert rc == 2 and "--overlay" in capsys.readouterr().err
