"""calibrate-depth refuses impossible radii and scales: a radius or scale
that is 0, negative or not finite exits 2 at parse time and writes nothing; contact circles
that cannot belong to a ball of that size at that scale (a 10x wrong --px-per-mm, which used
to report a *lower* held-out error) exit 2 naming the flags."""

from __future__ import annotations

import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.depth.calibration import Circle
from tactile_force.edge.errors import DatasetError

from tests.conftest import shared_data

GS_PX_PER_MM = 33.898  # GelSight Mini: 0.0295 mm/px
FOTS_PX_PER_MM = 19.58


@pytest.mark.parametrize("radius, scale, flag", [
    ("0", str(GS_PX_PER_MM), "--ball-radius-mm"), ("-3", str(GS_PX_PER_MM), "--ball-radius-mm"),
    ("nan", str(GS_PX_PER_MM), "--ball-radius-mm"), ("inf", str(GS_PX_PER_MM), "--ball-radius-mm"),
    ("2.0", "0", "--px-per-mm"), ("2.0", "-1", "--px-per-mm"), ("2.0", "nan", "--px-per-mm"),
])
def test_impossible_radius_or_scale_exits_2_and_writes_nothing(tmp_path, capsys, radius, scale, flag):
    out = tmp_path / "cal.npz"
    rc = cli_main(["calibrate-depth", str(shared_data("gelsight_mini_ball_presses.npz")), "--ball-radius-mm", radius,
                   "--px-per-mm", scale, "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 2 and flag in err and "number > 0 and <= " in err, err
    assert not out.exists()


@pytest.mark.parametrize("factor", [10.0, 0.1])
def test_a_ten_times_wrong_scale_is_refused_naming_the_flags(tmp_path, capsys, factor):
    for presses, extra, scale in (
            (shared_data("gelsight_mini_ball_presses.npz"), [], GS_PX_PER_MM),
            (shared_data("fots_digit", "ball_presses"),
             ["--background", str(shared_data("digit_backgrounds", "fots_digit_bg.png"))], FOTS_PX_PER_MM)):
        radius = "2.0" if presses.suffix == ".npz" else "2.35"
        out = tmp_path / f"{presses.stem}_{factor}.npz"
        rc = cli_main(["calibrate-depth", str(presses), *extra, "--ball-radius-mm", radius,
                       "--px-per-mm", str(scale * factor), "-o", str(out)])
        err = capsys.readouterr().err
        assert rc == 2 and "--px-per-mm" in err and "--ball-radius-mm" in err, err
        assert not out.exists()


def test_the_true_scale_still_calibrates(tmp_path, capsys):
    out = tmp_path / "cal.npz"
    rc = cli_main(["calibrate-depth", str(shared_data("gelsight_mini_ball_presses.npz")), "--ball-radius-mm", "2.0",
                   "--px-per-mm", str(GS_PX_PER_MM), "-o", str(out)])
    assert rc == 0 and out.is_file(), capsys.readouterr().err


def test_check_circle_scale_rules():
    from tactile_force.edge.depth.calibration import check_circle_scale

    circles = [Circle(120, 160, 30.0), Circle(100, 150, 35.0)]
    assert check_circle_scale(circles, (320, 240), 2.35, 19.58) == pytest.approx(2.35 * 19.58)
    with pytest.raises(DatasetError, match="larger than the 320x240 frame"):
        check_circle_scale(circles, (320, 240), 2.35, 195.8)
    with pytest.raises(DatasetError, match="cannot be larger than the ball"):
        check_circle_scale(circles, (320, 240), 2.35, 1.958)
    with pytest.raises(DatasetError, match="too large"):
        check_circle_scale([Circle(120, 160, 5.0)], (320, 240), 2.35, 19.58)
    with pytest.raises(DatasetError, match="finite number > 0"):
        check_circle_scale(circles, (320, 240), 0.0, 19.58)
