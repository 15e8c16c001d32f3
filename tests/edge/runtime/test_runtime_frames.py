"""Frames and contact masks from a run into the MCAP log: a real replay of the shared
AUROVA frames, the real gate and ONNX Runtime model, a real MCAP file read back."""

from __future__ import annotations

import json
import shutil
import textwrap

import cv2
import numpy as np
import pytest

pytest.importorskip("mcap", reason="MCAP output needs the 'mcap' extra")
pytest.importorskip("cyclonedds", reason="MCAP output serialises CDR with cyclonedds (the 'mcap' extra)")

from tactile_force.edge.cli import main as cli_main  # noqa: E402
from tactile_force.edge.errors import SceneError  # noqa: E402
from tactile_force.edge.outputs.mcap_log import read_messages  # noqa: E402
from tactile_force.edge.runtime import frame_sinks  # noqa: E402
from tactile_force.edge.scene import build_scene, load_scene, parse_scene, scene_from_flags  # noqa: E402

from tests.conftest import shared_data  # noqa: E402

WRENCH = "geometry_msgs/msg/WrenchStamped"


def _by_topic(path) -> dict[str, list]:
    out: dict[str, list] = {}
    for m in read_messages(path):
        out.setdefault(m.topic, []).append(m)
    return out


def _png(data: bytes) -> np.ndarray:
    """The image bytes at the end of a CDR CompressedImage: from the PNG signature on."""
    start = data.index(b"\x89PNG")
    img = cv2.imdecode(np.frombuffer(data[start:], np.uint8), cv2.IMREAD_UNCHANGED)
    assert img is not None
    return img


def _replay_with_untouched_frames(tmp_path, aurova_dir, bg) -> tuple:
    """A replay folder (in tmp_path): the no-contact image three times, then the AUROVA grasp."""
    folder = tmp_path / "replay" / "images"
    folder.mkdir(parents=True)
    for i in range(3):
        shutil.copy(bg, folder / f"{1000 + i}.png")
    grasp = sorted((aurova_dir / "images").glob("*.png"))
    for f in grasp:
        shutil.copy(f, folder / f.name)
    return folder.parent, 3 + len(grasp)


def test_run_with_mcap_frames_logs_every_frame_and_mask(tmp_path, monkeypatch, rgb_bundle, aurova_dir, capsys):
    bg = shared_data("digit_backgrounds", "aurova_background_b.png")
    replay, n_frames = _replay_with_untouched_frames(tmp_path, aurova_dir, bg)
    monkeypatch.chdir(tmp_path)
    readings = tmp_path / "r.jsonl"
    assert cli_main(["run", "--source", str(replay), "--bundle", str(rgb_bundle), "--background", str(bg),
                     "--name", "left", "--out", "run.mcap", "--out", str(readings), "--mcap-frames"]) == 0
    topics = _by_topic(tmp_path / "run.mcap")
    n = len(topics["/tactile/force"])
    assert n == n_frames == 14
    images, masks = topics["/tactile/left/image/compressed"], topics["/tactile/left/contact_mask/compressed"]
    assert len(images) == len(masks) == n  # one frame and one mask per gated frame
    assert all(m.type_name == "sensor_msgs/msg/CompressedImage" for m in images + masks)
    assert [m.log_time_ns for m in images] == [m.log_time_ns for m in topics["/tactile/force"]]
    rows = [json.loads(line) for line in readings.read_text().splitlines()]
    decoded = [_png(m.data) for m in masks]
    assert all(d.shape == (320, 240) and set(np.unique(d)) <= {0, 255} for d in decoded)
    contact = ["no_contact" not in r["flags"].split("|") for r in rows]
    assert any(contact) and not all(contact)  # the replay has presses and no-contact frames
    for c, d in zip(contact, decoded):
        assert (int(np.count_nonzero(d)) > 0) == c  # the mask shows the contact exactly when the gate saw one
    img = cv2.imdecode(np.frombuffer(images[0].data[images[0].data.index(b"\xff\xd8"):], np.uint8), cv2.IMREAD_COLOR)
    assert img is not None and img.shape == (320, 240, 3)


def test_scene_output_frames_only_and_zero_cost_without(tmp_path, monkeypatch, rgb_bundle, aurova_dir):
    bg = shared_data("digit_backgrounds", "aurova_background_b.png")
    monkeypatch.chdir(tmp_path)
    scene_file = tmp_path / "s.toml"
    scene_file.write_text(textwrap.dedent(f"""
        [runtime]
        bundle = "{rgb_bundle}"
        [[sensor]]
        name = "right"
        source = "replay"
        path = "{aurova_dir}"
        background = "{bg}"
        [[output]]
        kind = "mcap"
        path = "frames.mcap"
        frames = true
        [[output]]
        kind = "mcap"
        path = "plain.mcap"
    """))
    scene = load_scene(scene_file)
    assert [(o.frames, o.mask) for o in scene.outputs] == [(True, False), (False, False)]
    built = build_scene(scene)
    try:
        assert len(frame_sinks(built.sinks)) == 1
        built.runtime.run(built.sinks)
        assert built.runtime.tap == (True, False)
    finally:
        built.close()
    with_frames, plain = _by_topic(tmp_path / "frames.mcap"), _by_topic(tmp_path / "plain.mcap")
    assert len(with_frames["/tactile/right/image/compressed"]) == 11
    assert "/tactile/right/contact_mask/compressed" not in with_frames
    assert set(plain) == {"/tactile/force", "/tactile/force/diagnostics", "/tactile/force/interval"}

    # No writer wants frames: nothing is copied or kept.
    built = build_scene(load_scene(scene_file))
    try:
        plain_only = [s for s in built.sinks if not getattr(s, "frames", False)]
        built.runtime.run(plain_only, max_frames=3)
        assert built.runtime.tap == (False, False) and built.runtime.tapped == []
    finally:
        built.close()


def test_frames_and_mask_keys_are_for_mcap_only(tmp_path):
    with pytest.raises(SceneError, match=r"'frames' is for kind = \"mcap\" only"):
        parse_scene({"sensor": [{"source": "virtual"}], "output": [{"kind": "csv", "path": "x.csv", "frames": True}]},
                    tmp_path / "s.toml")
    with pytest.raises(SceneError, match=r"output\[0\]\.mask: expected true or false, got 1"):
        parse_scene({"sensor": [{"source": "virtual"}], "output": [{"kind": "mcap", "path": "x.mcap", "mask": 1}]},
                    tmp_path / "s.toml")
    with pytest.raises(SceneError, match="--mcap-frames: no --out FILE.mcap"):
        scene_from_flags("virtual", outputs=["x.csv"], mcap_frames=True)


def test_mcap_frames_flag_needs_source_mode(tmp_path, capsys):
    scene_file = tmp_path / "s.toml"
    scene_file.write_text('[[sensor]]\nsource = "virtual"\n')
    assert cli_main(["run", "--scene", str(scene_file), "--mcap-frames"]) == 2
    assert "--mcap-frames: only with --source" in capsys.readouterr().err
