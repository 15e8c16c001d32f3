"""Scenes and CLI flags validated once, before anything heavy is loaded; one error contract
(exit 0 success, 1 a check failed, 2 bad input) and no traceback for anything a user typed.

Each case here is one bullet of the robustness issue: on the old code each gave a
traceback, a late failure or exit 0."""

from __future__ import annotations

import dataclasses
import os
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.cli import scene as cli_scene
from tactile_force.edge.errors import SceneError
from tactile_force.edge.scene import load_scene

from tests.conftest import shared_data

SENSOR = '[[sensor]]\nname = "left"\nsource = "camera"\n'

#: (scene text, the words the error must hold: the dotted key, what was expected, what was got)
BAD_SCENES = {
    "gate threshold a string": ('[gate]\nthreshold = "high"\n' + SENSOR,
                                r"gate\.threshold: expected a number > 0 and < 255, got 'high'"),
    "gate background_frames a string": ('[gate]\nbackground_frames = "5"\n' + SENSOR,
                                        r"gate\.background_frames: expected an integer in \[1, 10000\], got '5'"),
    "runtime not a table": ("runtime = 5\n" + SENSOR, r"runtime: expected a table, got 5"),
    "sensor a list of numbers": ("sensor = [1, 2]\n", r"sensor\[0\]: expected a table, got 1"),
    "fps inf": (SENSOR + "fps = inf\n", r"sensor\[0\]\.fps: expected a finite number in \[0\.01, 10000\], got inf"),
    "fps nan": (SENSOR + "fps = nan\n", r"sensor\[0\]\.fps: expected a finite number in \[0\.01, 10000\], got nan"),
    "fps a word": (SENSOR + 'fps = "fast"\n', r"sensor\[0\]\.fps: expected a number in \[0\.01, 10000\], got 'fast'"),
    "n_grasps 0": ('[[sensor]]\nsource = "virtual"\nn_grasps = 0\n',
                   r"sensor\[0\]\.n_grasps: expected an integer in \[1, 10000\] \(grasps the virtual DIGIT plays\), got 0"),
    "deadline inf": ("[runtime]\ndeadline_ms = inf\n" + SENSOR,
                     r"runtime\.deadline_ms: expected a finite number > 0, got inf"),
    "gate per sensor bool for float": (SENSOR + "gate = { threshold = true }\n",
                                       r"sensor\[0\]\.gate\.threshold: expected a number > 0 and < 255, got True"),
    "output not a table": ("output = 3\n" + SENSOR, r"output: expected \[\[output\]\] tables, got 3"),
    "ros2 without topic": (SENSOR + '[[output]]\nkind = "ros2"\n', r"output\[0\]: output 'ros2' needs 'topic'"),
    "mcap without path": (SENSOR + '[[output]]\nkind = "mcap"\n', r"output\[0\]: output 'mcap' needs 'path'"),
    "source a list": ("[[sensor]]\nsource = [1]\n", r"sensor\[0\]\.source: expected one of 'camera', .*got \[1\]"),
    "source a table": ("[[sensor]]\nsource = { a = 1 }\n",
                       r"sensor\[0\]\.source: expected one of 'camera', .*got \{'a': 1\}"),
    "unknown top-level table": ("[sensors]\n" + SENSOR,
                                r": unknown key 'sensors'; allowed keys: runtime, gate, depth, sensor, output"),
    "17 sensors": ("".join(f'[[sensor]]\nname = "s{k}"\nsource = "virtual"\n' for k in range(17)),
                   r"sensor: 17 \[\[sensor\]\] tables; expected 1 to 16 \(one runtime serves at most 16 sensors"),
    "two DIGITs with one serial": ("".join(f'[[sensor]]\nname = "{n}"\nsource = "digit"\nserial = "{s}"\n'
                                           for n, s in (("thumb", "D20001"), ("index", "D20002"), ("ring", "D20001"))),
                                   r"sensor\[2\]\.serial: DIGIT 'D20001' is also sensor\[0\] \(thumb\); expected one "
                                   r"\[\[sensor\]\] table per device"),
    "one camera twice": ('[[sensor]]\nname = "a"\nsource = "camera"\ndevice = 2\n'
                         '[[sensor]]\nname = "b"\nsource = "camera"\ndevice = "/dev/video2"\n',
                         r"sensor\[1\]\.device: camera '/dev/video2' is also sensor\[0\] \(a\)"),
}


def test_a_hand_of_digits_by_serial_parses(tmp_path):
    """Up to 16 sensors; DIGITs enumerate by serial, one table each (no device is opened)."""
    serials = [f"D2000{k}" for k in range(8)]
    p = tmp_path / "hand.toml"
    p.write_text("".join(f'[[sensor]]\nname = "f{k}"\nsource = "digit"\nserial = "{s}"\n'
                         for k, s in enumerate(serials)))
    scene = load_scene(p)
    assert [s.serial for s in scene.sensors] == serials
    assert [s.name for s in scene.sensors] == [f"f{k}" for k in range(8)]


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scene_values_are_named_with_key_and_file(tmp_path, case):
    text, words = BAD_SCENES[case]
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(SceneError, match=words) as info:
        load_scene(p)
    assert str(info.value).startswith(f"{p}: ")  # one style: the file, then the dotted key


@pytest.mark.parametrize("case", sorted(BAD_SCENES))
def test_bad_scenes_exit_2_without_traceback(tmp_path, case, capsys):
    p = tmp_path / "bad.toml"
    p.write_text(BAD_SCENES[case][0])
    assert cli_main(["run", "--scene", str(p)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "error:" in err and str(p) in err
    assert cli_main(["scene", "show", str(p)]) == 2


def _replay_scene(tmp_path: Path, bundle: Path, replay: Path, csv: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(textwrap.dedent(f"""
        [runtime]
        bundle = "{bundle}"
        [[sensor]]
        name = "left"
        source = "replay"
        path = "{replay}"
        [[output]]
        kind = "csv"
        path = "{csv}"
        """))
    return p


def test_csv_path_that_is_a_folder_fails_before_the_model_is_loaded(tmp_path, rgb_bundle, aurova_dir, monkeypatch):
    (tmp_path / "out").mkdir()
    p = _replay_scene(tmp_path, rgb_bundle, aurova_dir, str(tmp_path / "out"))
    with pytest.raises(SceneError, match=r"output\[0\]\.path: .*out is a folder; expected a file path"):
        load_scene(p)
    loaded = []
    import tactile_force.edge.model.onnx_model as inference

    monkeypatch.setattr(inference.OnnxForceModel, "__init__", lambda *a, **k: loaded.append(1))
    assert cli_main(["run", "--scene", str(p)]) == 2
    assert loaded == []  # refused before any model was loaded


@pytest.mark.skipif(not Path("/proc/self").exists(), reason="needs /proc (a file system nobody can create files in)")
def test_unwritable_csv_path_fails_at_load(tmp_path, rgb_bundle, aurova_dir):
    p = _replay_scene(tmp_path, rgb_bundle, aurova_dir, "/proc/tactile_force_readings.csv")
    with pytest.raises(SceneError, match=r"output\[0\]\.path: .*cannot create files in /proc"):
        load_scene(p)


def test_output_inside_the_package_is_refused(tmp_path, rgb_bundle, aurova_dir):
    from tactile_force.edge.scene import PACKAGE_DIR

    p = _replay_scene(tmp_path, rgb_bundle, aurova_dir, str(PACKAGE_DIR / "scenes" / "readings.csv"))
    with pytest.raises(SceneError, match="inside the installed package"):
        load_scene(p)


def test_scene_show_exits_2_when_a_listed_file_is_missing(tmp_path, rgb_bundle, capsys):
    p = _replay_scene(tmp_path, rgb_bundle, tmp_path / "no_such_replay", str(tmp_path / "r.csv"))
    assert cli_main(["scene", "show", str(p)]) == 2
    out = capsys.readouterr()
    assert "[MISSING]" in out.out
    assert "no_such_replay not found" in out.err and "Traceback" not in out.err


def test_scene_show_fails_on_a_scene_run_would_crash_on(tmp_path, make_bundle, aurova_dir, capsys):
    """A depth bundle with no colour->normal mapping anywhere: run cannot build its depth stage."""
    p = _replay_scene(tmp_path, make_bundle("show_rgbd", variant="rgbmod+d"), aurova_dir, str(tmp_path / "r.csv"))
    assert cli_main(["scene", "show", str(p)]) == 2
    err = capsys.readouterr().err
    assert f"{p}: depth.mapping: missing" in err
    assert cli_main(["run", "--scene", str(p)]) == 2
    assert "Traceback" not in capsys.readouterr().err


def test_scene_show_exits_0_on_a_good_scene(tmp_path, rgb_bundle, aurova_dir, capsys):
    p = _replay_scene(tmp_path, rgb_bundle, aurova_dir, str(tmp_path / "r.csv"))
    assert cli_main(["scene", "show", str(p)]) == 0
    assert "source:left" in capsys.readouterr().out


def test_all_corrupt_replay_folder_exits_2_with_a_message(tmp_path, rgb_bundle, capsys):
    folder = tmp_path / "corrupt"
    folder.mkdir()
    for i in range(4):
        (folder / f"{i}.png").write_bytes(b"\x89PNG not really")
    p = _replay_scene(tmp_path, rgb_bundle, folder, str(tmp_path / "r.csv"))
    assert cli_main(["run", "--scene", str(p)]) == 2
    err = capsys.readouterr().err
    assert "produced no reading" in err and "4 corrupt" in err and "Traceback" not in err


def test_vga_video_exits_2_with_a_message(tmp_path, rgb_bundle, capsys):
    video = tmp_path / "vga.avi"
    w = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (640, 480))
    if not w.isOpened():
        pytest.skip("OpenCV cannot write MJPG .avi here")
    for _ in range(5):
        w.write(np.full((480, 640, 3), 120, np.uint8))
    w.release()
    assert cli_main(["run", "--source", str(video), "--bundle", str(rgb_bundle)]) == 2
    err = capsys.readouterr().err
    assert "640x480" in err and "Traceback" not in err


@pytest.mark.parametrize("argv, words", [
    (["demo", "--grasps", "0"], "argument --grasps: 0: expected an integer in [1, 10000]"),
    (["demo", "--threads", "0"], "argument --threads: 0: expected an integer in [1, 1024]"),
    (["demo", "--threads", "two"], "argument --threads: 'two' is not an integer"),
    (["run", "--scene", "x.toml", "--max-frames", "-1"], "expected an integer in [1, 1000000000000]"),
    (["run", "--scene", "x.toml", "--max-frames", "0"], "expected an integer in [1, 1000000000000]"),
    (["run", "--source", "virtual", "--fps", "inf"], "expected a finite number in [0.01, 10000]"),
])
def test_bad_flags_exit_2_with_a_clear_line(argv, words, capsys):
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_demo_out_that_is_a_file_exits_2(tmp_path, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert cli_main(["demo", "--out", str(f)]) == 2
    assert "is a file; expected an output folder" in capsys.readouterr().err


def test_debug_flag_shows_the_traceback(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text(BAD_SCENES["fps inf"][0])
    with pytest.raises(SceneError):
        cli_main(["--debug", "run", "--scene", str(p)])


def test_internal_errors_are_one_line_exit_1(monkeypatch, capsys):
    def broken(args):
        raise ZeroDivisionError("float division by zero")

    monkeypatch.setattr(cli_scene, "main", broken)
    assert cli_main(["scene", "show", "x.toml"]) == 1
    err = capsys.readouterr().err
    assert "internal error: ZeroDivisionError" in err and "--debug" in err and "Traceback" not in err


def test_os_errors_on_user_paths_exit_2(monkeypatch, capsys):
    def unreadable(args):
        raise PermissionError(13, "Permission denied", "/data/scene.toml")

    monkeypatch.setattr(cli_scene, "main", unreadable)
    assert cli_main(["scene", "show", "/data/scene.toml"]) == 2
    assert "error: /data/scene.toml: Permission denied" in capsys.readouterr().err


def test_every_sensor_lost_is_a_failed_check_exit_1(tmp_path, rgb_bundle, capsys):
    """A replay folder deleted mid-run: the source raises, the sensor is dropped; the run
    made readings before, so it is not bad input but a failed run (exit 1)."""
    import shutil

    folder = tmp_path / "vanishing"
    shutil.copytree(shared_data("aurova_digit_grasp"), folder)
    p = _replay_scene(tmp_path, rgb_bundle, folder, str(tmp_path / "r.csv"))
    from tactile_force.edge.sources import files as sources

    real = sources.ReplayFolderSource._load

    def load_then_vanish(self, i):
        if i == 3:
            shutil.rmtree(folder)
        return real(self, i)

    sources.ReplayFolderSource._load = load_then_vanish
    try:
        assert cli_main(["run", "--scene", str(p)]) == 1
    finally:
        sources.ReplayFolderSource._load = real
    err = capsys.readouterr().err
    assert "every sensor was lost" in err and "disappeared" in err and "Traceback" not in err
    assert os.path.exists(tmp_path / "r.csv")


# -- property: any TOML-shaped table gives a Scene or a SceneError, never anything else ------
def _toml_values():
    from hypothesis import strategies as st

    scalars = st.one_of(st.integers(-3, 70), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
                        st.text(max_size=8), st.sampled_from(["camera", "replay", "virtual", "digit", "gelsight_mini",
                                                              "video", "csv", "ros2", "mcap", "cpu", "oak", "paper"]))
    return st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                         st.dictionaries(st.text(max_size=6), inner, max_size=3)),
                        max_leaves=6)


def _table_of(keys):
    from hypothesis import strategies as st

    return st.dictionaries(st.sampled_from(sorted(keys)), _toml_values(), max_size=5)


def test_any_scene_table_parses_or_names_the_problem(tmp_path):
    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st
    from tactile_force.edge.scene import SOURCE_KINDS, DepthSettings, OutputSpec, RuntimeSettings, parse_scene

    def names(cls):
        return {f.name for f in dataclasses.fields(cls)}

    sensor_keys = {k for kind in SOURCE_KINDS.values() for k in names(kind.keys)}
    sensor = st.fixed_dictionaries({"source": st.one_of(st.sampled_from(sorted(SOURCE_KINDS)), _toml_values())},
                                   optional={k: _toml_values() for k in sorted(sensor_keys - {"source"})})
    gate_keys = {"threshold", "background_frames", "blur", "downscale", "convex_hull", "refresh_rate"}
    scene = st.fixed_dictionaries({}, optional={
        "runtime": st.one_of(_table_of(names(RuntimeSettings)), _toml_values()),
        "gate": st.one_of(_table_of(gate_keys), _toml_values()),
        "depth": st.one_of(_table_of(names(DepthSettings)), _toml_values()),
        "sensor": st.one_of(st.lists(st.one_of(sensor, _table_of(sensor_keys)), max_size=3), _toml_values()),
        "output": st.one_of(st.lists(_table_of(names(OutputSpec)), max_size=3), _toml_values()),
    })

    @settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
    @given(scene)
    def check(data):
        try:
            parse_scene(data, tmp_path / "scene.toml")
        except SceneError as exc:
            assert str(exc).startswith(f"{tmp_path / 'scene.toml'}: ")

    check()


def test_two_outputs_on_one_file_are_refused(tmp_path, rgb_bundle, aurova_dir):
    p = _replay_scene(tmp_path, rgb_bundle, aurova_dir, str(tmp_path / "r.csv"))
    p.write_text(p.read_text() + f'\n[[output]]\nkind = "jsonl"\npath = "{tmp_path / "r.csv"}"\n')
    with pytest.raises(SceneError, match="used by more than one output"):
        load_scene(p)
