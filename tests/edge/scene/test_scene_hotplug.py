"""The scene's `digit` kind follows unplug / replug through udev events: a fake
libudev and fake V4L2 cameras at the hardware boundary (tests/bridge/fake_udev.py), the real
scene parsing, build_scene, UdevWatcher, HotplugSource, DigitSource, gates, ONNX Runtime model
and ForceRuntime above them."""

from __future__ import annotations

import time

import pytest
from tactile_force.edge.scene import build_scene, parse_scene, scene_from_flags, scene_to_toml
from tactile_force.edge.scene import kinds as scene_mod
from tactile_force.firmware_bridge import DeviceKind
from tactile_force.firmware_bridge.hotplug import HotplugSource, UdevWatcher

from tests.bridge.fake_udev import FakeUdevContext
from tests.bridge.test_hotplug import Cameras, _digit
from tests.conftest import shared_data


@pytest.fixture
def udev(monkeypatch, portraits, tmp_path):
    """Two DIGITs on a fake udev; the scene's watcher listens to it; DigitSource opens fake
    cameras (open_v4l2) and finds no sysfs device behind a /dev path (empty sysfs tree)."""
    from tactile_force.firmware_bridge import digit

    ctx = FakeUdevContext()
    ctx.plug(_digit("1-2", "D20001", 5, [2, 3]), announce=False)
    ctx.plug(_digit("1-3", "D20002", 6, [4, 5]), announce=False)
    cams = Cameras(portraits, ctx)
    (tmp_path / "sys" / "bus" / "usb" / "devices").mkdir(parents=True)
    real_locate = digit.locate_sensor
    monkeypatch.setattr(digit, "locate_sensor",
                        lambda sensor, find, _roots=(): real_locate(sensor, find, (tmp_path / "sys", tmp_path)))
    monkeypatch.setattr(digit, "open_v4l2", cams)
    monkeypatch.setattr(scene_mod, "_udev_state", {"watcher": UdevWatcher(ctx, ctx.monitor)})
    ctx.cams = cams
    return ctx


def _two_digits(tmp_path, **left):
    bg = shared_data("digit_backgrounds", "aurova_background_b.png")
    return parse_scene({"sensor": [{"name": "left", "source": "digit", "serial": "D20001", "background": str(bg),
                                    **left},
                                   {"name": "right", "source": "digit", "serial": "D20002", "background": str(bg)}]},
                       tmp_path / "s.toml")


def test_scene_digit_is_a_hotplug_source_that_survives_unplug(udev, tmp_path):
    built = build_scene(_two_digits(tmp_path))
    rt = built.runtime
    left, right = (s.source for s in rt.sensors)
    assert isinstance(left, HotplugSource) and isinstance(right, HotplugSource)
    assert (left.serial, right.serial, left.name) == ("D20001", "D20002", "left")
    readings: dict[str, list] = {"left": [], "right": []}

    def run_until(cond, timeout_s=30.0):
        end = time.monotonic() + timeout_s
        while not cond():
            assert time.monotonic() < end, f"timed out: {[(k, len(v)) for k, v in readings.items()]}"
            for r in rt.step():
                readings[r.sensor].append(r)

    try:
        run_until(lambda: len(readings["left"]) >= 3 and len(readings["right"]) >= 3)
        udev.unplug("1-2")
        udev.cams.opened["/dev/video2"].release()
        run_until(lambda: left.state == "waiting for replug")
        n_left, n_right = len(readings["left"]), len(readings["right"])
        run_until(lambda: len(readings["right"]) >= n_right + 10)  # the other finger is served
        assert len(readings["left"]) <= n_left + 1
        udev.plug(_digit("1-2", "D20001", 9, [6, 7]))  # back at a new node
        run_until(lambda: len(readings["left"]) >= n_left + 5)
    finally:
        built.close()
    assert left.nodes == ["/dev/video2", "/dev/video6"] and left.replugs == 1 and right.replugs == 0
    assert all(s.alive for s in rt.sensors) and rt.stats.source_errors == 0


def test_hotplug_false_and_no_udev_give_a_plain_digit_source(udev, tmp_path, monkeypatch, caplog, portraits):
    from tactile_force.firmware_bridge import digit, discovery
    from tactile_force.firmware_bridge.digit import DigitSource

    from tests.bridge.fakes import FakeCamera, FakeSysfsDevice, landscape, make_fake_sysfs

    # The plain DigitSource finds its DIGIT by serial on a (fake) sysfs tree.
    roots = make_fake_sysfs(tmp_path / "hw", [FakeSysfsDevice("1-2", 0x2833, 0x0209, 0x0200, "D20001",
                                                              videos=[(2, 0)]),
                                              FakeSysfsDevice("1-3", 0x2833, 0x0209, 0x0200, "D20002",
                                                              devnum=6, videos=[(4, 0)])])
    monkeypatch.setattr(digit, "locate_sensor",
                        lambda sensor, find, _r=(): discovery.locate_sensor(sensor, find, roots))
    monkeypatch.setattr(digit, "open_v4l2", lambda node: FakeCamera([landscape(p) for p in portraits]))
    scene = _two_digits(tmp_path, hotplug=False)
    assert scene.sensors[0].hotplug is False and scene.sensors[1].hotplug is True
    assert "hotplug = false" in scene_to_toml(scene)
    built = build_scene(scene)
    try:
        left, right = (s.source for s in built.runtime.sensors)
        assert type(left) is DigitSource and isinstance(right, HotplugSource)
    finally:
        built.close()

    # No pyudev / libudev: one warning, then plain DigitSources.
    def no_udev(*a, **k):
        raise ImportError("No module named 'pyudev'")

    monkeypatch.setattr(scene_mod, "_udev_state", {})
    monkeypatch.setattr("tactile_force.firmware_bridge.hotplug.UdevWatcher", no_udev)
    with caplog.at_level("WARNING", logger="tactile_force.edge.scene"):
        built = build_scene(_two_digits(tmp_path))
        try:
            assert all(type(s.source) is DigitSource for s in built.runtime.sensors)
        finally:
            built.close()
    scene_warnings = [r.message for r in caplog.records if r.name.startswith("tactile_force.edge.scene")]
    assert len(scene_warnings) == 1  # once for the process, though two DIGITs were opened
    assert "hot-plug unavailable" in scene_warnings[0] and "pyudev" in scene_warnings[0]


def test_cli_digit_source_uses_hotplug(udev):
    scene = scene_from_flags("digit:D20002")
    assert scene.sensors[0].hotplug is True
    src = scene_mod.open_source(scene.sensors[0])
    try:
        assert isinstance(src, HotplugSource) and src.kind is DeviceKind.DIGIT and src.serial == "D20002"
        assert src.read().frame.shape == (320, 240, 3)
    finally:
        src.close()
