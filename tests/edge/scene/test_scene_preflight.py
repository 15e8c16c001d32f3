"""``scene show`` makes every check ``run`` makes before it opens a device and answers as ``run``
would (exit code and message); a path with an unset ``$VARIABLE`` is refused naming the key and
the variable, never run with the variable left in the path."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import cv2
import numpy as np
import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.errors import SceneError
from tactile_force.edge.scene import load_scene

SENSOR = {
    "virtual": 'source = "virtual"\nn_grasps = 1',
    "camera": 'source = "camera"\ndevice = "/dev/video_not_attached_77"',
    "digit": 'source = "digit"\nserial = "D99999"\nhotplug = false',
}


def _write(tmp_path: Path, sensor: str, outputs: list[str], extra: str = "") -> Path:
    scene = tmp_path / "scene.toml"
    text = f'[runtime]\nbundle = "default"\n\n[[sensor]]\nname = "left"\n{sensor}\n{extra}\n'
    for path in outputs:
        text += f'\n[[output]]\nkind = "csv"\npath = "{path}"\n'
    scene.write_text(text)
    return scene


def _both(scene: Path, capsys, *flags: str) -> tuple[int, str, int, str]:
    rc_show = cli_main(["scene", "show", str(scene), *flags])
    show = capsys.readouterr().err
    rc_run = cli_main(["run", "--scene", str(scene), "--max-frames", "3", *flags])
    run = capsys.readouterr().err
    return rc_show, show, rc_run, run


def _cases(tmp_path: Path, aurova_dir: Path) -> dict[str, tuple[Path, list[str]]]:
    """name -> (scene file, the words both answers must hold)."""
    for sub in "abcdefg":
        (tmp_path / sub).mkdir()
    out = {}
    existing = tmp_path / "earlier.csv"
    existing.write_text("a user's readings\n")
    out["an output that exists"] = (_write(tmp_path / "a", SENSOR["virtual"], [existing.as_posix()]),
                                    ["output[0].path", "already exists", "--force"])
    scene_b = tmp_path / "b" / "scene.toml"
    out["an output that is the scene file"] = (_write(tmp_path / "b", SENSOR["virtual"], [scene_b.as_posix()]),
                                               ["output[0].path", "is the input --scene"])
    frames = tmp_path / "frames"
    shutil.copytree(aurova_dir, frames)
    inside = (frames / "readings.csv").as_posix()
    out["an output inside the replay folder"] = (
        _write(tmp_path / "c", f'source = "replay"\npath = "{frames.as_posix()}"', [inside]),
        ["output[0].path", "is inside the input sensor left path"])
    out["a camera that is not attached"] = (_write(tmp_path / "d", SENSOR["camera"], []),
                                            ["sensor[0] (left)", "video_not_attached_77: no such device"])
    out["a DIGIT that is not attached"] = (_write(tmp_path / "e", SENSOR["digit"], []),
                                           ["sensor[0] (left)", "DIGIT 'D99999' not attached"])
    bg = tmp_path / "vga.png"
    cv2.imwrite(str(bg), np.full((480, 640, 3), 90, np.uint8))
    out["a background of another size"] = (
        _write(tmp_path / "f", SENSOR["virtual"], [], extra=f'background = "{bg.as_posix()}"'),
        ["sensor[0] (left).background", "480x640"])
    dangling = tmp_path / "dangling"
    dangling.mkdir()
    shutil.copy(aurova_dir / "images" / "1500.png", dangling / "1.png")
    (dangling / "2.png").symlink_to(tmp_path / "gone.png")
    out["a replay folder with a dangling link"] = (
        _write(tmp_path / "g", f'source = "replay"\npath = "{dangling.as_posix()}"', []),
        ["sensor[0] (left).path", "2.png is a dangling symbolic link"])
    return out


CASE_NAMES = ["an output that exists", "an output that is the scene file", "an output inside the replay folder",
              "a camera that is not attached", "a DIGIT that is not attached", "a background of another size",
              "a replay folder with a dangling link"]


@pytest.mark.parametrize("case", CASE_NAMES)
def test_scene_show_answers_as_run_would(tmp_path, aurova_dir, capsys, case):
    scene, words = _cases(tmp_path, aurova_dir)[case]
    rc_show, show, rc_run, run = _both(scene, capsys)
    assert rc_run == 2, run
    assert rc_show == 2, show  # exit 0 before: scene show missed what run refuses at once
    for w in words:
        assert w in show and w in run, (w, show, run)
    assert "Traceback" not in show + run


def test_scene_show_force_checks_as_run_force(tmp_path, capsys):
    existing = tmp_path / "earlier.csv"
    existing.write_text("a user's readings\n")
    scene = _write(tmp_path, SENSOR["virtual"], [existing.as_posix()])
    assert cli_main(["scene", "show", str(scene)]) == 2
    assert cli_main(["scene", "show", str(scene), "--force"]) == 0
    capsys.readouterr()
    inputs = _write(tmp_path, SENSOR["virtual"], [scene.as_posix()])  # the scene file itself: never, --force or not
    assert cli_main(["scene", "show", str(inputs), "--force"]) == 2
    assert "is the input --scene" in capsys.readouterr().err


# -- unset variables ----------------------------------------------------------------------------
@pytest.mark.parametrize("written, key", [
    ("$TF_TEST_UNSET_DIR/readings.csv", "output[0].path"),
    ("${TF_TEST_UNSET_DIR}/readings.csv", "output[0].path"),
])
def test_an_unset_variable_in_an_output_path_is_refused_naming_key_and_variable(tmp_path, monkeypatch, capsys,
                                                                                 written, key):
    monkeypatch.delenv("TF_TEST_UNSET_DIR", raising=False)
    monkeypatch.chdir(tmp_path)
    scene = _write(tmp_path, SENSOR["virtual"], [written])
    with pytest.raises(SceneError, match=rf"{re.escape(key)}: environment variable \$\{{?TF_TEST_UNSET_DIR\}}? is not set"):
        load_scene(scene)
    rc_show, show, rc_run, run = _both(scene, capsys)
    assert rc_show == rc_run == 2 and "TF_TEST_UNSET_DIR" in show and "TF_TEST_UNSET_DIR" in run
    assert not any(tmp_path.rglob("readings.csv"))  # nothing written anywhere (before: ./$TF_TEST_UNSET_DIR/...)


def test_an_unset_variable_in_an_input_path_is_refused_naming_it(tmp_path, monkeypatch):
    monkeypatch.delenv("TF_TEST_UNSET_DIR", raising=False)
    scene = _write(tmp_path, 'source = "replay"\npath = "$TF_TEST_UNSET_DIR/frames"', [])
    with pytest.raises(SceneError, match=r"sensor\[0\]\.path: environment variable \$TF_TEST_UNSET_DIR is not set"):
        load_scene(scene)


def test_a_set_variable_is_expanded(tmp_path, monkeypatch):
    monkeypatch.setenv("TF_TEST_OUT_DIR", str(tmp_path / "out"))
    scene = _write(tmp_path, SENSOR["virtual"], ["$TF_TEST_OUT_DIR/readings.csv"])
    assert load_scene(scene).outputs[0].path == tmp_path / "out" / "readings.csv"


def test_an_unset_variable_in_a_flag_path_is_refused_naming_the_flag(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("TF_TEST_UNSET_DIR", raising=False)
    monkeypatch.chdir(tmp_path)
    rc = cli_main(["run", "--source", "virtual", "--max-frames", "3", "--out", "$TF_TEST_UNSET_DIR/r.csv"])
    err = capsys.readouterr().err
    assert rc == 2 and "--out" in err and "$TF_TEST_UNSET_DIR is not set" in err, err
    assert not any(tmp_path.rglob("r.csv"))
