"""A scene path that is not what it should be is named for what it is: a scene file that is
a folder, a FIFO or a dangling link ("scene file not found" before), a background that is a
FIFO; and a ``$VARIABLE`` in a scene path that is not set or set to "" is named (the shipped
replay scene read "/digit_backgrounds/...: not found" with TACTILE_FORCE_SHARED_DATA="")."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from tactile_force.edge.cli import main as cli_main

REPLAY_SCENE = Path(__file__).resolve().parents[3] / "edge" / "scenes" / "replay_rgbmod.toml"


def _run_scene(scene: Path, capsys, verb: tuple[str, ...] = ("run", "--scene")) -> tuple[int, str]:
    rc = cli_main([*verb, str(scene)])
    cap = capsys.readouterr()
    return rc, cap.out + cap.err


@pytest.mark.parametrize("verb", [("run", "--scene"), ("scene", "show")], ids=["run", "scene show"])
def test_a_scene_path_that_is_not_a_regular_file_says_what_it_is(tmp_path, capsys, verb):
    folder = tmp_path / "scene.toml"
    folder.mkdir()
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)
    dangling = tmp_path / "dangling.toml"
    os.symlink(tmp_path / "gone.toml", dangling)
    for path, what in ((folder, "is a folder"), (fifo, "is a FIFO"),
                       (dangling, f"is a symbolic link to a missing {tmp_path / 'gone.toml'}"),
                       (tmp_path / "missing.toml", "scene file not found")):
        rc, out = _run_scene(path, capsys, verb)
        assert rc == 2 and str(path) in out and what in out and "a regular TOML file" in out, out
        assert "Traceback" not in out


def test_a_background_that_is_a_fifo_is_named_as_one(tmp_path, capsys):
    fifo = tmp_path / "bg.png"
    os.mkfifo(fifo)
    scene = tmp_path / "s.toml"
    scene.write_text(textwrap.dedent(f"""\
        [[sensor]]
        source = "virtual"
        background = "{fifo}"
        """))
    rc, out = _run_scene(scene, capsys, ("scene", "show"))
    assert rc == 2 and f"{fifo} is a FIFO; expected a regular file or a folder" in out, out


@pytest.mark.parametrize("value", [None, ""], ids=["unset", "empty"])
def test_the_shipped_replay_scene_names_the_variable_it_needs(value):
    """Run as a user would, in a fresh process whose environment lacks the variable (or holds it empty)."""
    env = {k: v for k, v in os.environ.items() if k != "TACTILE_FORCE_SHARED_DATA"}
    if value is not None:
        env["TACTILE_FORCE_SHARED_DATA"] = value
    for verb in (["run", "--scene"], ["scene", "show"]):
        proc = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", *verb, str(REPLAY_SCENE)],
                              capture_output=True, text=True, env=env, timeout=120)
        state = "is not set" if value is None else "is empty"
        assert proc.returncode == 2, proc.stderr
        assert f"environment variable $TACTILE_FORCE_SHARED_DATA {state}" in proc.stderr, proc.stderr
        assert "/digit_backgrounds/" not in proc.stderr.replace("$TACTILE_FORCE_SHARED_DATA/digit_backgrounds", "")


def test_an_empty_variable_in_a_flag_path_is_named(monkeypatch, capsys):
    monkeypatch.setenv("MY_DATA", "")
    rc = cli_main(["run", "--source", "$MY_DATA/grasp", "--max-frames", "1"])
    err = capsys.readouterr().err
    assert rc == 2 and "--source" in err and "environment variable $MY_DATA is empty" in err, err
