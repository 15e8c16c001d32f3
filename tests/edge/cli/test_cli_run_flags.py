"""``tactile-force run`` without a scene file, the error summary vs ground truth, learning
the background, --save-scene, and the progress bar / plot everyday pieces."""

from __future__ import annotations

import csv
import io
import json
import textwrap
from pathlib import Path

import cv2
import numpy as np
import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.cli.replay_report import PLOT_NAME, _plot_cv
from tactile_force.edge.cli.run import LearningStatus
from tactile_force.edge.errors import SceneError
from tactile_force.edge.reading import Flags, ForceReading
from tactile_force.edge.report.plots import nice_ticks
from tactile_force.edge.scene import load_scene, parse_scene, scene_from_flags

from tests.conftest import shared_data

from tests.conftest import REPO  # noqa: E402


@pytest.fixture
def aurova_bg() -> Path:
    return shared_data("digit_backgrounds", "aurova_background_b.png")


def test_run_from_flags_ends_with_re_and_mae_per_bin(tmp_path, monkeypatch, rgb_bundle, aurova_dir, aurova_bg,
                                                     capsys):
    monkeypatch.chdir(tmp_path)
    rc = cli_main(["run", "--source", str(aurova_dir), "--bundle", str(rgb_bundle), "--background", str(aurova_bg),
                   "--out", "rel/readings.csv", "--out", "readings.jsonl"])
    out = capsys.readouterr()
    assert rc == 0, out.err
    recs = [json.loads(x) for x in (tmp_path / "readings.jsonl").read_text().splitlines()]
    cnn = [r for r in recs if "no_contact" not in r["flags"] and "invalid_input" not in r["flags"]]
    assert len(recs) == 11 and len(cnn) >= 8
    assert f"error vs truth over {len(cnn)} CNN readings: RE" in out.err and "MAE" in out.err
    bins = [line for line in out.err.splitlines() if line.strip().split(" ")[0].count("-") == 1 and " N: RE " in line]
    assert len(bins) == len({int(r["truth_n"]) for r in cnn}) >= 2  # one line per 1 N bin present
    rows = list(csv.DictReader((tmp_path / "rel" / "readings.csv").open()))  # relative to the cwd
    assert len(rows) == 11 and all(r["sensor"] == "sensor" for r in rows)
    assert len([ln for ln in out.out.splitlines() if "sensor #" in ln]) == 11  # one stdout line per reading


def test_error_summary_matches_metrics_on_the_readings(tmp_path, rgb_bundle, aurova_dir, aurova_bg, capsys):
    from tactile_force.edge.data.metrics import error_stats

    out_csv = tmp_path / "r.jsonl"
    assert cli_main(["run", "--source", str(aurova_dir), "--bundle", str(rgb_bundle), "--background",
                     str(aurova_bg), "--out", str(out_csv)]) == 0
    recs = [json.loads(x) for x in out_csv.read_text().splitlines()]
    recs = [r for r in recs if "no_contact" not in r["flags"] and "invalid_input" not in r["flags"]]
    es = error_stats([r["force_n"] for r in recs], [r["truth_n"] for r in recs])
    err = capsys.readouterr().err
    assert f"RE {es.re_mean:.3f} +- {es.re_std:.3f}, MAE {es.mae_mean:.3f} +- {es.mae_std:.3f} N" in err


def test_flags_build_the_same_scene_as_a_toml_file(tmp_path, monkeypatch, rgb_bundle, aurova_dir, aurova_bg):
    monkeypatch.chdir(tmp_path)
    from_flags = scene_from_flags(str(aurova_dir), bundle=str(rgb_bundle), background=str(aurova_bg),
                                  outputs=["r.csv"], name="left")
    toml = tmp_path / "s.toml"
    toml.write_text(textwrap.dedent(f"""
        [runtime]
        bundle = "{rgb_bundle}"
        [[sensor]]
        name = "left"
        source = "replay"
        path = "{aurova_dir}"
        background = "{aurova_bg}"
        [[output]]
        kind = "stdout"
        [[output]]
        kind = "csv"
        path = "r.csv"
        """))
    from_file = load_scene(toml)
    assert from_flags.sensors == from_file.sensors
    assert from_flags.outputs == from_file.outputs and from_flags.bundles == from_file.bundles


def test_save_scene_round_trips_and_runs(tmp_path, monkeypatch, rgb_bundle, aurova_dir, aurova_bg, capsys):
    monkeypatch.chdir(tmp_path)
    assert cli_main(["run", "--source", str(aurova_dir), "--bundle", str(rgb_bundle), "--background", str(aurova_bg),
                     "--out", "a.csv", "--fps", "200", "--save-scene", "saved/scene.toml", "--max-frames", "3"]) == 0
    saved = tmp_path / "saved" / "scene.toml"
    assert "wrote scene" in capsys.readouterr().err
    again = load_scene(saved)
    first = scene_from_flags(str(aurova_dir), bundle=str(rgb_bundle), background=str(aurova_bg), outputs=["a.csv"],
                             fps=200.0)
    assert again.sensors == first.sensors and again.outputs == first.outputs and again.bundles == first.bundles
    assert cli_main(["run", "--scene", str(saved)]) == 2  # a.csv exists: refused without --force
    assert "already exists" in capsys.readouterr().err
    assert cli_main(["run", "--scene", str(saved), "--force"]) == 0
    assert len((tmp_path / "a.csv").read_text().splitlines()) == 12


def test_save_scene_keeps_non_default_gate_and_kind_keys(tmp_path):
    from tactile_force.edge.scene import scene_to_toml

    data = {"gate": {"threshold": 20.0}, "sensor": [
        {"name": "l", "source": "gelsight_mini", "device": "2BNK-CEGG"},
        {"name": "r", "source": "digit", "serial": "D20001", "fps": 30, "gate": {"blur": 7}}]}
    scene = parse_scene(data, tmp_path / "s.toml")
    (tmp_path / "back.toml").write_text(scene_to_toml(scene))
    back = load_scene(tmp_path / "back.toml")
    assert back.sensors == scene.sensors


@pytest.mark.parametrize("argv, words", [
    (["run", "--source", "no/such/folder"], "--source 'no/such/folder': no such folder or file"),
    (["run", "--source", "virtual", "--out", "x.txt"], "--out 'x.txt': unknown file type .txt"),
    (["run", "--source", "digit:"], "digit:SERIAL"),
    (["run"], "give --scene FILE, or --source SRC"),
    (["run", "--scene", "a.toml", "--source", "virtual"], "not both"),
    (["run", "--scene", "a.toml", "--bundle", "b"], "--bundle: only with --source"),
    (["run", "--source", "virtual", "--bundle", "no/such/bundle"], "no/such/bundle not found"),
])
def test_bad_run_flags_exit_2(argv, words, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli_main(argv) == 2
    err = capsys.readouterr().err
    assert words in err and "Traceback" not in err


def test_learning_the_background_says_so_and_warns_on_contact(tmp_path, rgb_bundle, aurova_dir, capsys):
    """No --background: the first five frames are learnt; the AUROVA frames are all in
    contact (the press changes frame to frame), so the run warns."""
    assert cli_main(["run", "--source", str(aurova_dir), "--bundle", str(rgb_bundle), "--out",
                     str(tmp_path / "r.csv")]) == 0
    err = capsys.readouterr().err
    assert "learning the background from the first 5 frames" in err
    assert "sensor: background learnt from 5 frames" in err
    assert "already differ like contact" in err


def test_a_clean_learnt_background_gives_no_warning(tmp_path, rgb_bundle, aurova_bg, capsys):
    folder = tmp_path / "still"
    folder.mkdir()
    bg = cv2.imread(str(aurova_bg))
    for i in range(8):
        cv2.imwrite(str(folder / f"{i}.png"), bg)
    assert cli_main(["run", "--source", str(folder), "--bundle", str(rgb_bundle)]) == 0
    err = capsys.readouterr().err
    assert "learning the background" in err and "already differ like contact" not in err


def test_learning_shows_on_the_live_status_line():
    from tactile_force.edge.outputs import StdoutWriter

    live, done = io.StringIO(), io.StringIO()
    status, learnt = StdoutWriter(live=True, stream=live), LearningStatus(done)
    for i in range(3):
        r = ForceReading("left", i, i, 0.0, Flags.NO_CONTACT, detail="learning background")
        status.write(r)
        learnt.write(r)
    assert live.getvalue().count("learning background") == 3 and done.getvalue() == ""
    r = ForceReading("left", 3, 3, 0.0, Flags.NO_CONTACT)
    status.write(r)
    learnt.write(r)
    assert "learning background" not in live.getvalue().rsplit("\r", 1)[-1]
    assert "left: background learnt from 3 frames" in done.getvalue()


def test_progress_uses_tqdm(monkeypatch, capsys):
    from tactile_force.edge.report.progress import progress

    monkeypatch.setenv("TACTILE_FORCE_PROGRESS", "1")
    assert list(progress(range(7), desc="frames")) == list(range(7))
    err = capsys.readouterr().err
    assert "frames: 100%" in err and "7/7" in err  # tqdm's bar
    monkeypatch.delenv("TACTILE_FORCE_PROGRESS")
    assert list(progress(iter(range(3)), total=3, enabled=False)) == [0, 1, 2]
    assert capsys.readouterr().err == ""


def test_nice_ticks_are_round_and_cover_the_range():
    assert nice_ticks(0.0, 15.0) == [0, 5, 10, 15]
    assert nice_ticks(0.0, 3.7) == [0.0, 1.0, 2.0, 3.0]
    t = nice_ticks(0.0, 0.9)
    assert t[0] == 0.0 and t[-1] <= 0.9 and len(t) >= 4


def test_opencv_plot_has_tick_labels_and_axis_titles(tmp_path):
    path = tmp_path / "p.png"
    t = np.linspace(0, 4, 80)
    _plot_cv(t, np.sin(t) * 4 + 5, np.sin(t) * 4 + 5.2, path)
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    left_margin, bottom_margin = img[40:300, 0:66], img[316:360, 70:880]
    assert (left_margin < 128).sum() > 200  # y tick labels and the rotated y title
    assert (bottom_margin < 128).sum() > 200  # x tick labels and "time (s)"


def test_readme_names_the_plot_the_demo_writes():
    assert PLOT_NAME in (REPO / "README.md").read_text()


def test_scene_from_flags_validates_like_a_file(tmp_path):
    with pytest.raises(SceneError, match=r"^command line: sensor\[0\]\.fps: expected 60 or 30 \(QVGA frame rates of a DIGIT\), got 45$"):
        scene_from_flags("digit:D20001", fps=45.0)


def test_run_from_flags_writes_an_mcap_log(tmp_path, monkeypatch, rgb_bundle, aurova_dir, aurova_bg, capsys):
    """The issue's must-show: a replay run from flags ends with RE/MAE and leaves an MCAP file
    that the mcap reader lists with one WrenchStamped message per reading."""
    pytest.importorskip("mcap", reason="the 'mcap' extra is not installed")
    pytest.importorskip("tactile_force.edge.outputs.mcap_log", reason="MCAP output not written yet")
    from mcap.reader import make_reader

    monkeypatch.chdir(tmp_path)
    assert cli_main(["run", "--source", str(aurova_dir), "--bundle", str(rgb_bundle), "--background", str(aurova_bg),
                     "--out", "run.mcap"]) == 0
    assert "error vs truth over" in capsys.readouterr().err
    with open(tmp_path / "run.mcap", "rb") as fh:
        summary = make_reader(fh).get_summary()
    counts = {summary.schemas[c.schema_id].name: summary.statistics.channel_message_counts.get(cid, 0)
              for cid, c in summary.channels.items()}
    assert counts["geometry_msgs/msg/WrenchStamped"] == 11


def test_ros2_and_mcap_flags_become_scene_outputs(tmp_path, monkeypatch):
    from tactile_force.edge.scene import OutputSpec

    monkeypatch.chdir(tmp_path)
    scene = scene_from_flags("virtual", outputs=["log.mcap"], ros2="/tactile/force")
    assert scene.outputs[1:] == [OutputSpec("mcap", tmp_path / "log.mcap"), OutputSpec("ros2", topic="/tactile/force")]
    with pytest.raises(SceneError, match="output 'ros2' writes no file; remove 'path'"):
        parse_scene({"sensor": [{"source": "virtual"}], "output": [{"kind": "ros2", "topic": "/t", "path": "x"}]},
                    tmp_path / "s.toml")
