"""Scenes from one registry of source kinds: presets, the DIGIT-by-serial kind, package:
mappings, paper depth mode's reference from the gate's background, and closing the model."""

from __future__ import annotations

import dataclasses
import textwrap
import typing
from pathlib import Path

import cv2
import numpy as np
import pytest
from tactile_force.edge.errors import SceneError, SourceError
from tactile_force.edge.gate.options import GateOptions
from tactile_force.edge.reading import Flags
from tactile_force.edge.runtime import ASSETS_DIR
from tactile_force.edge.scene import (
    SOURCE_KINDS,
    SensorKeys,
    build_scene,
    describe_scene,
    load_scene,
    open_source,
    parse_scene,
)
from tactile_force.edge.typed_json import field_check, read_value

from tests.conftest import shared_data


def test_every_source_kind_has_keys_preset_and_opener():
    assert set(SOURCE_KINDS) == {"camera", "digit", "gelsight_mini", "replay", "video", "virtual"}
    hints = typing.get_type_hints
    for name, kind in SOURCE_KINDS.items():
        assert kind.name == name
        assert isinstance(kind.gate_preset(), GateOptions)
        assert callable(kind.opener) and callable(kind.describe)
        assert issubclass(kind.keys, SensorKeys) and "fps" in kind.key_names
        for f in dataclasses.fields(kind.keys):  # a default must pass its own field's check
            if f.default is not dataclasses.MISSING and f.default is not None:
                read_value(hints(kind.keys)[f.name], f.default, f"{name}.{f.name}", field_check(f))


def test_gelsight_mini_gets_its_gate_preset_unless_the_scene_sets_gate(tmp_path):
    base = {"sensor": [{"name": "g", "source": "gelsight_mini", "device": "2BNK-CEGG"}]}
    assert parse_scene(base, tmp_path / "s.toml").sensors[0].gate == GateOptions.gelsight_mini()
    # [gate] keys override the preset key by key; the rest of the preset stays
    s = parse_scene({**base, "gate": {"threshold": 20.0}}, tmp_path / "s.toml").sensors[0]
    assert s.gate == GateOptions.gelsight_mini(threshold=20.0) and s.gate.convex_hull
    cam = parse_scene({"sensor": [{"source": "camera"}]}, tmp_path / "s.toml").sensors[0]
    assert cam.gate == GateOptions() and cam.fps == 60.0
    assert parse_scene(base, tmp_path / "s.toml").sensors[0].fps == 25.0  # the GelSight kind's own default


def test_keys_of_another_kind_are_refused(tmp_path):
    with pytest.raises(SceneError, match=r"sensor\[0\]: unknown key 'n_grasps'; allowed keys: source, name, "
                                         r"background, gate, device, fps$"):
        parse_scene({"sensor": [{"source": "camera", "n_grasps": 2}]}, tmp_path / "s.toml")
    with pytest.raises(SceneError, match=r"sensor\[0\]\.serial: missing; expected a DIGIT serial such as 'D20001'"):
        parse_scene({"sensor": [{"source": "digit"}]}, tmp_path / "s.toml")
    with pytest.raises(SceneError, match=r"sensor\[0\]\.fps: expected 60 or 30 \(QVGA frame rates of a DIGIT\), "
                                         r"got 45$"):
        parse_scene({"sensor": [{"source": "digit", "serial": "D20001", "fps": 45}]}, tmp_path / "s.toml")


@pytest.fixture
def fake_digits(tmp_path, monkeypatch, portraits):
    """One DIGIT D20001 on a fake sysfs tree, streaming real frames through a fake camera
    (the V4L2 / USB boundary)."""
    from tactile_force.firmware_bridge import digit

    from tests.bridge.fakes import FakeCamera, FakeSysfsDevice, landscape, make_fake_sysfs

    roots = make_fake_sysfs(tmp_path / "hw", [FakeSysfsDevice("1-2", 0x2833, 0x0209, 0x0200, "D20001",
                                                              videos=[(4, 0)])])
    real_locate = digit.locate_sensor
    opened: list[str] = []

    def locate(sensor, find, _roots=()):
        return real_locate(sensor, find, roots)

    def open_camera(node):
        opened.append(str(node))
        return FakeCamera([landscape(p) for p in portraits])

    monkeypatch.setattr(digit, "locate_sensor", locate)
    monkeypatch.setattr(digit, "open_v4l2", open_camera)
    return opened


def test_digit_kind_opens_a_digit_by_serial(tmp_path, fake_digits, portraits):
    scene = parse_scene({"sensor": [{"name": "left", "source": "digit", "serial": "D20001"}]}, tmp_path / "s.toml")
    assert any("DIGIT D20001" in line for line in describe_scene(scene))
    src = open_source(scene.sensors[0])
    try:
        tf = src.read()
    finally:
        src.close()
    assert fake_digits[0].endswith("video4")  # the serial was resolved to its video node
    assert np.array_equal(tf.frame, portraits[0])


def test_digit_kind_names_the_serial_and_lists_attached_ones(tmp_path, fake_digits):
    scene = parse_scene({"sensor": [{"name": "left", "source": "digit", "serial": "D99999"}]}, tmp_path / "s.toml")
    with pytest.raises(SourceError, match=r"sensor 'left' \(digit D99999\).*'D99999' not attached.*D20001"):
        open_source(scene.sensors[0])
    assert fake_digits == []


def test_package_mapping_resolves_to_the_package_assets(tmp_path):
    data = {"depth": {"mapping": "package:virtual_digit_depth.npz"}, "sensor": [{"source": "camera"}]}
    scene = parse_scene(data, tmp_path / "sub" / "s.toml")
    assert scene.depth.mapping == ASSETS_DIR / "virtual_digit_depth.npz"
    assert scene.depth.mapping.is_file()


def _paper_scene(tmp_path: Path, bundle: Path, replay: Path, background: Path | None) -> Path:
    bg = f'background = "{background}"' if background else ""
    p = tmp_path / "paper.toml"
    p.write_text(textwrap.dedent(f"""
        [runtime]
        bundle = "{bundle}"
        deadline_ms = 1000.0

        [depth]
        mode = "paper"
        mapping = "{shared_data('aurova_digit_depth_mlp.npz')}"

        [[sensor]]
        name = "left"
        source = "replay"
        path = "{replay}"
        {bg}
        """))
    return p


def test_paper_depth_scene_runs_the_aurova_frames_with_no_invalid_input(tmp_path, make_bundle, aurova_dir):
    bundle = make_bundle("paper_rgbd", variant="rgbmod+d")
    bg = shared_data("digit_backgrounds", "aurova_background_b.png")
    built = build_scene(load_scene(_paper_scene(tmp_path, bundle, aurova_dir, bg)))
    readings = []
    stats = built.runtime.run([], on_reading=readings.append)
    built.close()
    assert stats.readings == 11 and stats.inferred >= 8  # the CNN ran on the contact frames
    assert stats.invalid == 0, [r.detail for r in readings if Flags.INVALID_INPUT in r.flags]
    assert all(np.isfinite(r.force_n) for r in readings)
    stage = built.runtime.sensors[0].depth
    assert stage.reference is not None and not stage.needs_reference


def test_paper_depth_reference_from_a_learnt_background(tmp_path, make_bundle, aurova_dir):
    """No background image: the gate learns it from the first no-contact frames and the
    runtime hands those same frames to the depth stage as its zero-depth reference."""
    from tactile_force.edge.data.dataset import AuthorsDataset, AuthorsDatasetWriter

    root = tmp_path / "grasp"
    bg = cv2.imread(str(shared_data("digit_backgrounds", "aurova_background_b.png")))
    with AuthorsDatasetWriter(root) as w:
        for _ in range(6):
            w.write(bg, 0.0)
        for s in AuthorsDataset(aurova_dir):
            w.write(s.frame, s.force_n)
    built = build_scene(load_scene(_paper_scene(tmp_path, make_bundle("paper_rgbd", variant="rgbmod+d"), root, None)))
    readings = []
    stats = built.runtime.run([], on_reading=readings.append)
    built.close()
    assert stats.invalid == 0, [r.detail for r in readings if Flags.INVALID_INPUT in r.flags]
    assert stats.inferred >= 8
    assert built.runtime.sensors[0].depth.reference is not None


def test_runtime_close_closes_the_model_and_the_sources(tmp_path, rgb_bundle, aurova_dir):
    data = {"runtime": {"bundle": str(rgb_bundle)},
            "sensor": [{"name": "left", "source": "replay", "path": str(aurova_dir)}]}
    built = build_scene(parse_scene(data, tmp_path / "s.toml"))
    model = built.runtime.model
    closed = []
    src = built.runtime.sensors[0].source
    real_close = src.close
    src.close = lambda: (closed.append("source"), real_close())
    assert model.session is not None
    built.close()
    assert model.session is None and closed == ["source"]
