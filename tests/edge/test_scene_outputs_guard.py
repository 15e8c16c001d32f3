"""A scene file's file outputs go through the output guard like ``run --out``: an existing
readings file is refused without ``--force`` (exit 2, naming the scene key), and an output
that would replace one of the scene's inputs is refused even with it (issue 19)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

SCENE = """
[runtime]
bundle = "default"

[[sensor]]
name = "virtual"
source = "virtual"
n_grasps = 1

[[output]]
kind = "csv"
path = "{out}"
"""


def _run(scene: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "run", "--scene", str(scene),
                           "--max-frames", "5", *extra], capture_output=True, text=True, timeout=300)


def test_existing_scene_output_is_refused_without_force(tmp_path: Path) -> None:
    out = tmp_path / "readings.csv"
    out.write_text("a user's earlier readings\n")
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(out=out.as_posix()))
    r = _run(scene)
    assert r.returncode == 2, r.stderr
    assert "output[0].path" in r.stderr and "already exists" in r.stderr and "--force" in r.stderr
    assert "Traceback" not in r.stderr
    assert out.read_text() == "a user's earlier readings\n"  # untouched
    r = _run(scene, "--force")
    assert r.returncode == 0, r.stderr
    assert out.read_text().splitlines()[0].startswith("sensor")  # replaced by a readings CSV, as asked


def test_scene_output_never_replaces_the_scene_file(tmp_path: Path) -> None:
    scene = tmp_path / "scene.toml"
    scene.write_text(SCENE.format(out=scene.as_posix()))
    before = scene.read_text()
    r = _run(scene, "--force")
    assert r.returncode == 2, r.stderr
    assert "is the input --scene" in r.stderr
    assert scene.read_text() == before
