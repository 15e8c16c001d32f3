"""The one plotting module (OpenCV only) and the verbs that draw with it: run, calibrate-force, compress."""

from __future__ import annotations

import sys

import cv2
import numpy as np
import pytest
from tactile_force.edge.cli import main
from tactile_force.edge.report.plots import ParetoPoint, calibration_plot, error_vs_latency, pareto_front
from tactile_force.edge.scene import default_bundle_path


@pytest.fixture(scope="module")
def labelled(tmp_path_factory):
    out = tmp_path_factory.mktemp("plots") / "data"
    assert main(["synth", "--out", str(out), "--n", "16", "--seed", "2", "--no-progress"]) == 0
    return out


def _ink(img: np.ndarray, colour_bgr: tuple[int, int, int], tol: int = 40) -> int:
    return int((np.abs(img.astype(int) - np.array(colour_bgr)).max(axis=-1) < tol).sum())


def test_pareto_front_keeps_only_undominated_points():
    pts = [ParetoPoint("a", 1.0, 0.10), ParetoPoint("b", 0.5, 0.20), ParetoPoint("c", 0.8, 0.25),
           ParetoPoint("d", 0.3, None), ParetoPoint("e", 2.0, 0.05), ParetoPoint("f", 1.0, 0.10)]
    front = pareto_front(pts)
    assert [pts[i].label for i in front if pts[i].label != "f"] == ["b", "a", "e"]
    assert 2 not in front and 3 not in front


def test_error_vs_latency_draws_points_and_the_budget_line(tmp_path):
    path = error_vs_latency([ParetoPoint("fp32", 0.6, 0.08), ParetoPoint("int8", 0.4, 0.09),
                             ParetoPoint("slow", 2.5, 0.07, measured=False)], 1.0, tmp_path / "p.png")
    img = cv2.imread(str(path))
    assert img.shape == (420, 900, 3)
    assert _ink(img, (40, 40, 220)) > 100  # the red dashed budget line
    assert _ink(img, (200, 110, 30)) > 100  # blue points
    # the budget line sits at x(1.0): left of the 2.5 ms point, right of the 0.6 ms one
    red_cols = np.where((np.abs(img.astype(int) - (40, 40, 220)).max(axis=-1) < 40).sum(axis=0) > 50)[0]
    assert red_cols.size and 70 + 0.3 * 810 < red_cols.mean() < 70 + 0.45 * 810


def test_a_second_p99_is_drawn_as_a_grey_mark_joined_to_its_point(tmp_path):
    """bench: the p99 at the cadence is the point, the back-to-back p99 a grey diamond beside it."""
    pts = [ParetoPoint("default", 0.9, 0.08), ParetoPoint("d", 1.4, 0.13)]
    plain = cv2.imread(str(error_vs_latency(pts, 1.0, tmp_path / "a.png")))
    both = cv2.imread(str(error_vs_latency([ParetoPoint(p.label, p.p99_ms, p.error, also_ms=p.p99_ms / 2)
                                            for p in pts], 1.0, tmp_path / "b.png", also="back to back")))
    assert _ink(both, (60, 60, 60), 20) > _ink(plain, (60, 60, 60), 20) + 40


def test_calibration_plot(tmp_path):
    t = np.linspace(1, 14, 20)
    path = calibration_plot(t, t * 1.2 + 0.5, t + 0.1, np.array([0.0, 17.3]), np.array([0.0, 14.0]),
                            tmp_path / "c.png")
    img = cv2.imread(str(path))
    assert _ink(img, (0, 140, 255)) > 100  # the orange fitted map


def test_run_on_a_labelled_replay_draws_force_and_truth_over_time(tmp_path, capsys, labelled):
    out = tmp_path / "run" / "readings.csv"
    out.parent.mkdir()
    assert main(["run", "--source", str(labelled), "--bundle", str(default_bundle_path()), "--out", str(out)]) == 0
    plot = out.parent / "readings_force_vs_time.png"
    assert f"wrote {plot}" in capsys.readouterr().err
    img = cv2.imread(str(plot))
    assert img is not None and _ink(img, (60, 60, 60), 10) > 50  # the truth line


def test_run_without_truth_draws_nothing(tmp_path, labelled):
    import shutil

    plain = tmp_path / "pngs"
    shutil.copytree(labelled / "images", plain)
    out = tmp_path / "r.csv"
    assert main(["run", "--source", str(plain), "--bundle", str(default_bundle_path()), "--out", str(out)]) == 0
    assert not (tmp_path / "r_force_vs_time.png").exists()


def test_calibrate_force_writes_its_plot_beside_the_bundle(tmp_path, capsys, labelled):
    out = tmp_path / "calibrated"
    assert main(["calibrate-force", str(default_bundle_path()), "--data", str(labelled), "--out", str(out)]) == 0
    plot = tmp_path / "calibrated_calibration.png"
    assert str(plot) in capsys.readouterr().out
    img = cv2.imread(str(plot))
    assert img is not None and _ink(img, (0, 140, 255)) > 50 and _ink(img, (40, 40, 220)) > 50


def test_compress_students_plot(tmp_path):
    pytest.importorskip("torch")
    from tactile_force.export.cli_compress import students_plot

    students = [{"name": "rgbmod-w0.125-s8", "p99_ms": 0.3, "vs_teacher": {"re_mean": 0.12}},
                {"name": "rgbmod-w0.25-s4", "p99_ms": 0.7, "vs_teacher": {"re_mean": 0.06}}]
    path = students_plot(students, 0.5, str(tmp_path))
    assert path == tmp_path / "students.png" and cv2.imread(str(path)) is not None


def test_plots_import_no_matplotlib():
    import subprocess

    code = ("import sys; sys.modules['matplotlib'] = None; import numpy as np; "
            "from tactile_force.edge.report.plots import force_vs_time; "
            "force_vs_time(np.arange(5.0), np.arange(5.0), None, sys.argv[1])")
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        run = subprocess.run([sys.executable, "-c", code, f"{d}/f.png"], capture_output=True, text=True)
        assert run.returncode == 0, run.stderr
        assert cv2.imread(f"{d}/f.png") is not None
