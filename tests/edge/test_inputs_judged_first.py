"""Inputs are judged before the work and errors name what they refuse: bench's --data without forces and
--background that is no image, compress's --ladder, the virtual DIGIT's indenters, a missing extra behind
an old module path; and a run says whether the host keeps up and whether its outputs delivered."""

from __future__ import annotations

import io
import shutil
import subprocess
import sys
import time

import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.errors import MissingExtraError, OptionsError
from tactile_force.edge.reading import Flags
from tactile_force.edge.report.keep_up import WARN_SHARE, WARN_WINDOWS, KeepUpWatch

from tests.conftest import REPO, shared_data


def test_bench_refuses_data_without_forces_and_a_background_that_is_no_image_before_measuring(tmp_path, capsys):
    images = shared_data("aurova_digit_grasp", "images")
    plain = tmp_path / "plain"
    shutil.copytree(images, plain)
    t0 = time.monotonic()
    assert cli_main(["bench", "--data", str(plain), "--out", str(tmp_path / "b1")]) == 2
    assert "--data" in capsys.readouterr().err
    nolabels = tmp_path / "nolabels"
    shutil.copytree(shared_data("aurova_digit_grasp"), nolabels)
    for f in (nolabels / "forces").iterdir():
        f.write_text("not a force\n")
    assert cli_main(["bench", "--data", str(nolabels), "--out", str(tmp_path / "b2")]) == 2
    err = capsys.readouterr().err
    assert "no frame with a true force" in err or "--data" in err
    text = tmp_path / "bg.png"
    text.write_text("a text file")
    assert cli_main(["bench", "--data", str(shared_data("aurova_digit_grasp")), "--background", str(text),
                     "--out", str(tmp_path / "b3")]) == 2
    err = capsys.readouterr().err
    assert "--background" in err and "not decodable" in err and "Traceback" not in err
    assert time.monotonic() - t0 < 30  # judged, not measured
    assert not any((tmp_path / n).exists() for n in ("b1", "b2", "b3"))


@pytest.mark.parametrize("ladder", ["0.25x4b", "", "0.25x4,", "0.25x4b11112", "x4", "0.25x", "0.25x4b1191"])
def test_a_ladder_that_is_not_widthxk_or_widthxkbnnnn_is_refused(ladder):
    pytest.importorskip("torch", reason="compress is the 'export' extra (torch)")
    from tactile_force.export.compress_options import CompressError, parse_ladder

    with pytest.raises(CompressError, match="--ladder"):
        parse_ladder(ladder)


def test_an_unknown_indenter_is_refused_naming_the_parameter():
    from tactile_force.edge import VirtualDigitSource

    with pytest.raises(OptionsError, match=r"VirtualDigitSource.indenters=.*unknown 'no_such_shape'"):
        VirtualDigitSource(indenters=["no_such_shape"])
    with pytest.raises(OptionsError, match="VirtualDigitSource.indenters.*empty"):
        VirtualDigitSource(indenters=[])


def test_the_old_ros2_messages_path_names_the_extra_where_cyclonedds_is_missing():
    code = ("import sys, warnings; sys.modules['cyclonedds'] = None; warnings.simplefilter('ignore')\n"
            "from tactile_force.edge.errors import MissingExtraError\n"
            "try:\n    import tactile_force.edge.ros2_messages\nexcept MissingExtraError as e:\n    print('EXTRA', e.extra)")
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60)
    assert "EXTRA ros2" in p.stdout, p.stderr
    assert issubclass(MissingExtraError, ImportError)


class _R:
    def __init__(self, flags: Flags) -> None:
        self.flags = flags


def test_keep_up_reports_each_window_with_late_or_stale_readings_and_warns_once():
    now = [0.0]
    out = io.StringIO()
    w = KeepUpWatch(out, clock=lambda: now[0], window_s=10.0)
    for window in range(WARN_WINDOWS + 3):
        for i in range(100):
            now[0] = window * 10.0 + i * 0.1
            late = i < 20 if window < WARN_WINDOWS + 1 else False  # 20 % late, then on time
            w.write(_R(Flags.LATE if late else Flags(0)))  # type: ignore[arg-type]
    text = out.getvalue()
    assert text.count("late 20 %") == WARN_WINDOWS + 1 and text.count("warning: this host is not keeping up") == 1
    assert "late 0 %" not in text  # a window where all kept up says nothing
    assert w.summary().startswith("late 13.3 %") and "did not keep up" in w.summary()
    assert WARN_SHARE < 0.2


def test_keep_up_stays_quiet_below_the_level():
    now = [0.0]
    out = io.StringIO()
    w = KeepUpWatch(out, clock=lambda: now[0], window_s=10.0)
    for i in range(1000):
        now[0] = i * 0.1
        w.write(_R(Flags.STALE if i % 50 == 0 else Flags(0)))  # type: ignore[arg-type]
    assert "warning" not in out.getvalue() and not w.warned and "stale 2.0 %" in w.summary()


def test_a_replay_read_unpaced_is_plotted_against_its_frame_index(tmp_path):
    import cv2
    import numpy as np
    from tactile_force.edge.cli.replay_report import INDEX_AXIS, plot_force
    from tactile_force.edge.reading import ForceReading

    fields = ForceReading.__dataclass_fields__
    assert "frame_index" in fields and "timestamp_ns" in fields
    readings = []
    for i in range(5):
        r = ForceReading.__new__(ForceReading)
        object.__setattr__(r, "frame_index", 10 + i)
        object.__setattr__(r, "timestamp_ns", 1000 + i)
        object.__setattr__(r, "force_n", 1.0 + i)
        object.__setattr__(r, "truth_n", 1.5 + i)
        readings.append(r)
    a, b = tmp_path / "index.png", tmp_path / "time.png"
    plot_force(readings, a, by_index=True)
    plot_force(readings, b)
    ia, ib = cv2.imread(str(a)), cv2.imread(str(b))
    assert ia is not None and ib is not None and not np.array_equal(ia, ib)  # another axis, another picture
    assert "frame" in INDEX_AXIS


def test_a_run_whose_only_output_delivered_nothing_says_so_and_does_not_exit_0(tmp_path):
    pytest.importorskip("zenoh", reason="the Zenoh output is the 'zenoh' extra (eclipse-zenoh)")
    import socket

    with socket.socket() as s:  # a loopback port where no router listens
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "tactile_force.edge.cli", "run", "--source", "virtual", "--max-frames", "20",
           "--zenoh", f"tcp/127.0.0.1:{port}", "--zenoh-retry"]
    p = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert p.returncode == 1, p.stderr
    assert "published 0, dropped 20" in p.stderr and "DELIVERED NOTHING" in p.stderr and "Traceback" not in p.stderr
    with_file = subprocess.run(cmd + ["--out", str(tmp_path / "r.csv")], capture_output=True, text=True, cwd=tmp_path,
                               timeout=120)
    assert with_file.returncode == 0, with_file.stderr  # the CSV got every reading: the run delivered
    assert "DELIVERED NOTHING" in with_file.stderr and "late " in with_file.stderr


@pytest.mark.parametrize("failed, errno_, want", [
    ("ro/res/report.json", 13, "--out ro/res: error: ro/res/report.json: "),
    ("ro/.res.1a2b.partial", 13, "--out ro/res: error: ro/.res.1a2b.partial: "),  # its staging folder beside it
    ("ro", 30, "--out ro/res: error: ro: "),
    ("bundles/b/model.json", 13, "--bundle bundles/b: error: bundles/b/model.json: "),
    (None, 28, "--out ro/res: error: "),  # a full disk while writing an open file names the outputs
    ("elsewhere/x", 13, "error: elsewhere/x: "),
])
def test_an_os_error_names_the_flag_and_path_the_user_gave(failed, errno_, want):
    import argparse
    import os
    from pathlib import Path

    from tactile_force.edge.cli.main import _exit_code, path_flag_named

    p = argparse.ArgumentParser()
    p.add_argument("--out", type=Path)
    p.add_argument("--bundle", nargs="+")
    args = p.parse_args(["--out", "ro/res", "--bundle", "bundles/b"])
    exc = OSError(errno_, os.strerror(errno_), failed) if failed else OSError(errno_, os.strerror(errno_))
    assert path_flag_named(_exit_code(exc)[1], exc, args, p).startswith(want)
