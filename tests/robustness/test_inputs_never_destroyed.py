"""Inputs are never destroyed: no verb deletes or replaces an input
(source bundle, checkpoint, presses folder, anything in them, a folder holding them),
``--force`` included; an existing output needs ``--force``; special files are refused at
once. Each case is the user's command through the real CLI; the inputs are checked
byte for byte afterwards."""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from tactile_force.edge.bundle.store import write_bundle
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.errors import BundleError, TactileForceError
from tactile_force.edge.scene import default_bundle_path

from benchmarks.robustness import make_dataset, write_frame_png
from tests.conftest import shared_data

TF_CLI = Path(__file__).with_name("tf_cli.py")


def tree_digest(root: Path) -> dict[str, str]:
    """relative path -> sha256 of every file under ``root``."""
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


@pytest.fixture
def holder(tmp_path) -> Path:
    """A user's folder holding a source bundle and other files."""
    h = tmp_path / "work"
    shutil.copytree(default_bundle_path(), h / "src")
    (h / "notes.txt").write_text("my notes\n")
    return h


@pytest.fixture
def presses(tmp_path) -> Path:
    return Path(shutil.copytree(shared_data("aurova_digit_grasp"), tmp_path / "presses"))


def test_calibrate_force_out_holding_the_source_is_refused_with_force(holder, presses, capsys):
    before = tree_digest(holder)
    rc = cli_main(["calibrate-force", str(holder / "src"), "--data", str(presses), "--out", str(holder), "--force"])
    err = capsys.readouterr().err
    assert rc == 2 and "--out" in err and "holds the input" in err, err
    assert tree_digest(holder) == before


def test_calibrate_force_out_onto_the_presses_is_refused_with_force(holder, presses, capsys):
    before = tree_digest(presses)
    rc = cli_main(["calibrate-force", str(holder / "src"), "--data", str(presses), "--out", str(presses), "--force"])
    err = capsys.readouterr().err
    assert rc == 2 and "is the input --data" in err, err
    assert tree_digest(presses) == before


def test_calibrate_force_out_inside_the_source_is_refused(holder, presses, capsys):
    before = tree_digest(holder)
    rc = cli_main(["calibrate-force", str(holder / "src"), "--data", str(presses), "--out", str(holder / "src" / "c")])
    assert rc == 2 and "inside the input" in capsys.readouterr().err
    assert tree_digest(holder) == before


@pytest.fixture(scope="module")
def tiny_checkpoint(tmp_path_factory) -> Path:
    torch = pytest.importorskip("torch", reason="export needs torch (the 'export' extra)")
    from tactile_force.export import ModelSpec, build_model
    from tactile_force.export.checkpoint import save_checkpoint

    torch.manual_seed(0)
    root = tmp_path_factory.mktemp("ckpt")
    return save_checkpoint(root / "ckpt.pth", build_model("rgbmod", 0.125), ModelSpec("rgbmod", 0.125, 1 / 8))


def test_export_out_holding_the_checkpoint_is_refused_with_force(tiny_checkpoint, tmp_path, capsys):
    folder = tmp_path / "run1"
    folder.mkdir()
    ckpt = Path(shutil.copy(tiny_checkpoint, folder / "ckpt.pth"))
    (folder / "log.txt").write_text("training log\n")
    before = tree_digest(folder)
    rc = cli_main(["export", str(ckpt), "--out", str(folder), "--force"])
    err = capsys.readouterr().err
    assert rc == 2 and "holds the input checkpoint" in err, err
    assert tree_digest(folder) == before


def test_quantize_onto_its_source_is_refused_with_force(tiny_checkpoint, tmp_path, capsys):
    fp32 = tmp_path / "fp32"
    assert cli_main(["export", str(tiny_checkpoint), "--out", str(fp32), "--tolerance", "1e-3"]) == 0
    before = tree_digest(fp32)
    rc = cli_main(["quantize", str(fp32), "--out", str(fp32), "--mode", "int8-dynamic", "--force"])
    err = capsys.readouterr().err
    assert rc == 2 and "is the input bundle" in err, err
    assert tree_digest(fp32) == before
    # a real new output is fine, and --force replaces it (it is a bundle, and no input)
    out = tmp_path / "int8"
    assert cli_main(["quantize", str(fp32), "--out", str(out), "--mode", "int8-dynamic"]) == 0
    assert cli_main(["quantize", str(fp32), "--out", str(out), "--mode", "int8-dynamic"]) == 2
    assert "already exists" in capsys.readouterr().err
    assert cli_main(["quantize", str(fp32), "--out", str(out), "--mode", "int8-dynamic", "--force"]) == 0


def test_force_never_replaces_a_folder_that_is_not_a_bundle(tmp_path):
    from tactile_force.edge.files.guard import OutputKind, OutputRefused, check_output

    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "thesis.tex").write_text("x")
    src = default_bundle_path()
    from tactile_force.edge.bundle.store import load_bundle

    b = load_bundle(src)
    with pytest.raises(BundleError, match="not a bundle"):
        write_bundle(folder, b.onnx_path.read_bytes(), b.manifest, overwrite=True)
    assert (folder / "thesis.tex").read_text() == "x"
    with pytest.raises(OutputRefused, match="not a bundle"):
        check_output(folder, [], force=True, kind=OutputKind.BUNDLE)


@pytest.fixture
def replay(tmp_path) -> Path:
    return make_dataset(tmp_path / "replay", n=3)


def test_run_out_refuses_an_existing_file_without_force(replay, tmp_path, capsys):
    for suffix in (".csv", ".jsonl"):
        out = tmp_path / f"readings{suffix}"
        out.write_text("yesterday's readings\n")
        rc = cli_main(["run", "--source", str(replay), "--out", str(out)])
        err = capsys.readouterr().err
        assert rc == 2 and str(out) in err and "already exists" in err and "--force" in err, err
        assert out.read_text() == "yesterday's readings\n"
        assert cli_main(["run", "--source", str(replay), "--out", str(out), "--force"]) == 0
        capsys.readouterr()
        assert "yesterday" not in out.read_text() and out.stat().st_size > 0


def test_run_out_inside_the_replay_folder_is_refused(replay, capsys):
    before = tree_digest(replay)
    rc = cli_main(["run", "--source", str(replay), "--out", str(replay / "images" / "0.png.csv")])
    assert rc == 2 and "inside the input --source" in capsys.readouterr().err
    assert tree_digest(replay) == before


def test_calibrate_depth_refuses_an_existing_output_without_force(tmp_path, capsys):
    src = str(shared_data("gelsight_mini_ball_presses.npz"))
    out = tmp_path / "cal.npz"
    out.write_bytes(b"keep")
    rc = cli_main(["calibrate-depth", src, "--ball-radius-mm", "2.0", "--px-per-mm", "33.898", "-o", str(out)])
    assert rc == 2 and "already exists" in capsys.readouterr().err
    assert out.read_bytes() == b"keep"


def _fifo(path: Path) -> Path:
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    os.mkfifo(path)
    return path


def test_fifo_background_is_refused_at_once(replay, tmp_path):
    """A FIFO given as --background: exit 2 naming it, in a subprocess that must not hang."""
    fifo = _fifo(tmp_path / "bg.png")
    try:
        proc = subprocess.run([sys.executable, str(TF_CLI), "run", "--source", str(replay), "--background", str(fifo),
                               "--max-frames", "2"], capture_output=True, text=True, timeout=60)
    except subprocess.TimeoutExpired:
        pytest.fail("tactile-force run blocked on a FIFO --background")
    assert proc.returncode == 2 and str(fifo) in proc.stderr and "FIFO" in proc.stderr, proc.stderr
    assert "Traceback" not in proc.stderr


def test_special_file_input_is_refused_by_the_guard(tmp_path):
    from tactile_force.edge.files.guard import OutputKind, OutputRefused, check_output

    fifo = _fifo(tmp_path / "frames")
    with pytest.raises(OutputRefused, match="FIFO"):
        check_output(tmp_path / "out", [("--calib", fifo)], kind=OutputKind.BUNDLE)
    assert issubclass(OutputRefused, TactileForceError)


def test_export_parity_data_holding_the_output_is_refused(tiny_checkpoint, tmp_path, capsys):
    data = tmp_path / "frames"
    for i in range(3):
        write_frame_png(data / f"{i}.png", i)
    rc = cli_main(["export", str(tiny_checkpoint), "--out", str(data / "bundle"), "--parity-data", str(data)])
    assert rc == 2 and "inside the input --parity-data" in capsys.readouterr().err
    assert not (data / "bundle").exists()


def test_save_scene_refuses_an_existing_file_without_force(replay, tmp_path, capsys):
    scene = tmp_path / "mine.toml"
    scene.write_text("# my scene\n")
    rc = cli_main(["run", "--source", str(replay), "--save-scene", str(scene), "--max-frames", "1"])
    assert rc == 2 and "--save-scene" in capsys.readouterr().err
    assert scene.read_text() == "# my scene\n"
    assert cli_main(["run", "--source", str(replay), "--save-scene", str(scene), "--max-frames", "1", "--force"]) == 0
    assert "[[sensor]]" in scene.read_text()
