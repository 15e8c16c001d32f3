"""A scene file's file outputs go through the output guard like ``run --out``: an existing
readings file is refused without ``--force`` (exit 2, naming the scene key), and an output
that would replace one of the scene's inputs is refused even with it."""

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


def test_save_scene_never_replaces_an_input(tmp_path: Path) -> None:
    """--save-scene onto any input of the run (the background image, the bundle's files, the
    replay folder's frames) is refused, --force included, and the input is left as it was."""
    import shutil

    import cv2
    import numpy as np
    from tactile_force.edge import default_bundle_path

    replay = tmp_path / "replay"
    replay.mkdir()
    cv2.imwrite(str(replay / "0.png"), np.full((320, 240, 3), 90, np.uint8))
    bg = tmp_path / "bg.png"
    cv2.imwrite(str(bg), np.full((320, 240, 3), 90, np.uint8))
    bundle = tmp_path / "bundle"
    shutil.copytree(default_bundle_path(), bundle)
    for target in (bg, bundle / "model.json", replay / "0.png"):
        before = target.read_bytes()
        r = subprocess.run([sys.executable, "-m", "tactile_force.edge.cli", "run", "--source", str(replay),
                            "--bundle", str(bundle), "--background", str(bg), "--save-scene", str(target), "--force"],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 2, r.stderr
        assert "--save-scene" in r.stderr and "input" in r.stderr and "Traceback" not in r.stderr
        assert target.read_bytes() == before
