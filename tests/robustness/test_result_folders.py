"""Every verb that writes a folder of results publishes it whole: a new or empty --out, or
(--force) an earlier result of the same verb holding nothing else; never a half folder after an
interruption (exit 130 for SIGINT, 143 for SIGTERM, the previous result left as it was)."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from tactile_force.edge.cli import main
from tactile_force.edge.files.atomic import OUTPUT_MARK, foreign_files, staged_folder


def test_staged_folder_publishes_whole_or_leaves_the_previous_result(tmp_path):
    out = tmp_path / "r"
    with staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("1")
        assert not out.exists()  # nothing visible until the block ends
    assert (out / "a.txt").read_text() == "1" and foreign_files(out, "bench") == []
    assert json.loads((out / OUTPUT_MARK).read_text()) == {"verb": "bench", "files": ["a.txt"]}
    with pytest.raises(KeyboardInterrupt), staged_folder(out, "bench") as tmp:
        (tmp / "a.txt").write_text("half")
        raise KeyboardInterrupt
    assert (out / "a.txt").read_text() == "1"  # the previous result, untouched
    assert [p.name for p in tmp_path.iterdir()] == ["r"]  # no staging left


def test_foreign_files_name_what_the_verb_did_not_write(tmp_path):
    out = tmp_path / "r"
    with staged_folder(out, "study") as tmp:
        (tmp / "bundles").mkdir()
        (tmp / "bundles" / "x.onnx").write_text("x")
    (out / "bundles" / "NOTES.txt").write_text("mine")
    assert foreign_files(out, "study") == ["bundles/NOTES.txt"]
    assert foreign_files(out, "bench") == ["bundles/NOTES.txt", "bundles/x.onnx"]  # another verb's result


SYNTH = ["synth", "--n", "3", "--seed", "0", "--no-progress"]


def test_synth_never_adds_to_or_replaces_a_folder_unasked(tmp_path, capsys):
    out = tmp_path / "d"
    assert main([*SYNTH, "--out", str(out)]) == 0
    first = (out / "forces" / "force_0.txt").read_text()
    assert main([*SYNTH, "--out", str(out), "--seed", "1"]) == 2  # exists: --force needed
    assert "--force" in capsys.readouterr().err
    assert main([*SYNTH, "--out", str(out), "--seed", "1", "--force"]) == 0  # its own earlier dataset
    assert (out / "forces" / "force_0.txt").read_text() != first
    (out / "my_labels.txt").write_text("mine")
    assert main([*SYNTH, "--out", str(out), "--force"]) == 2  # a file synth did not write: never deleted
    assert (out / "my_labels.txt").read_text() == "mine"


def test_demo_replaces_only_its_own_earlier_result(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--grasps", "1"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert Path(summary["readings_csv"]) == out / "readings.csv"  # the published path, not the staging one
    assert main(["demo", "--out", str(out), "--grasps", "1"]) == 2
    assert main(["demo", "--out", str(out), "--grasps", "1", "--force"]) == 0
    (out / "notes.md").write_text("mine")
    assert main(["demo", "--out", str(out), "--grasps", "1", "--force"]) == 2
    assert (out / "notes.md").read_text() == "mine"


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_synth_leaves_no_half_dataset(tmp_path, sig):
    out = tmp_path / "d"
    proc = subprocess.Popen([sys.executable, "-m", "tactile_force.edge.cli", "synth", "--out", str(out), "--n",
                             "100000", "--no-progress"], stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    staging: list[Path] = []
    while time.monotonic() < deadline and not staging:  # rendering has started
        staging = [p for p in tmp_path.iterdir() if p.name.startswith(".d.")]
        time.sleep(0.05)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and not list((staging[0] / "images").glob("*.png")):
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 128 + int(sig), err
    assert "Traceback" not in err
    assert not out.exists() and list(tmp_path.iterdir()) == []
