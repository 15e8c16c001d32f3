"""Discovery classifies DIGIT / DIGIT-in-programming-mode / GelSight Mini from fake USB
descriptors and fake sysfs trees, and `tactile-force devices` reports it."""

import json

import pytest
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.errors import SourceError
from tactile_force.firmware_bridge import DeviceKind, bcd_to_revision, discover, find_digit, udev_rules_path

from .fakes import FakeSysfsDevice, FakeUsbDevice, fake_find, make_fake_sysfs


@pytest.fixture
def tree(tmp_path):
    return make_fake_sysfs(tmp_path, [
        FakeSysfsDevice("1-2", 0x2833, 0x0209, 0x0200, "D20001", "DIGIT", videos=[(2, 0), (3, 1)], devnum=5),
        FakeSysfsDevice("1-3", 0x2833, 0x0209, 0x0105, "D00042", "DIGIT", speed="12", videos=[(0, 0), (1, 1)],
                        devnum=6),
        FakeSysfsDevice("1-4", 0x0403, 0x0FDE, 0x0600, "FT1234", "DIGIT", devnum=7),
        FakeSysfsDevice("1-5", 0x0C45, 0x636D, 0x0100, None, "GelSight Mini R0B 2BNK-CEGG", videos=[(4, 0)],
                        devnum=8),
        FakeSysfsDevice("1-6", 0x046D, 0x0825, 0x0010, "ABC", "Webcam C270", videos=[(6, 0)], devnum=9),
    ])


def test_sysfs_tree_is_classified(tree):
    result = discover(*tree)
    assert result.method == "sysfs"
    by_port = {d.info.sysfs_path.rsplit("/", 1)[1]: d for d in result.devices}
    assert set(by_port) == {"1-2", "1-3", "1-4", "1-5"}  # the webcam is not ours

    good = by_port["1-2"]
    assert (good.kind, good.serial, good.firmware_revision) == (DeviceKind.DIGIT, "D20001", 200)
    assert good.info.video_nodes == [str(tree[1] / "video2"), str(tree[1] / "video3")]  # capture node first
    assert good.video_node.endswith("video2") and good.streamable and good.problems == []
    assert good.info.usb_node.endswith("bus/usb/001/005")

    slow = by_port["1-3"]
    assert slow.firmware_revision == 105
    assert any("12 Mb/s" in p and "cable" in p for p in slow.problems)
    assert any("revision 105 < 200" in p for p in slow.problems)

    prog = by_port["1-4"]
    assert prog.kind is DeviceKind.DIGIT_PROGRAMMING and not prog.streamable
    assert any("programming mode" in p for p in prog.problems)

    mini = by_port["1-5"]
    assert (mini.kind, mini.serial, mini.streamable) == (DeviceKind.GELSIGHT_MINI, "2BNK-CEGG", True)


def test_find_digit_by_serial_and_index(tree):
    result = discover(*tree)
    assert find_digit("D20001", result).video_node.endswith("video2")
    assert find_digit(1, result).serial == "D20001"  # index in serial order: D00042, D20001
    with pytest.raises(SourceError, match=r"D99999.*D20001.*programming mode"):
        find_digit("D99999", result)
    with pytest.raises(SourceError, match="index 5: 2 DIGIT"):
        find_digit("5", result)


def test_digit_without_video_node_cannot_stream(tmp_path):
    tree = make_fake_sysfs(tmp_path, [FakeSysfsDevice("2-1", 0x2833, 0x0209, 0x0200, "D11111")])
    result = discover(*tree)
    assert not result.devices[0].streamable
    with pytest.raises(SourceError, match="no /dev/video node"):
        find_digit("D11111", result)


def test_pyusb_descriptors_are_classified():
    fakes = [FakeUsbDevice(0x2833, 0x0209, 0x0201, "D30003", "DIGIT", speed=3, bus=3, address=4),
             FakeUsbDevice(0x2833, 0x0209, 0x0200, "D30004", speed=2),
             FakeUsbDevice(0x0403, 0x0FDE, 0x0600, "X"),
             FakeUsbDevice(0x0C45, 0x636D, 0x0100, "SN", "GelSight Mini R0B 28J3-CWXU"),
             FakeUsbDevice(0x2833, 0x0209, 0x0200, no_permission=True),
             FakeUsbDevice(0x1234, 0x5678)]
    result = discover("/nonexistent-sys", "/nonexistent-dev", find=fake_find(fakes))
    assert result.method == "pyusb"
    kinds = [(d.kind, d.serial) for d in result.devices]
    assert kinds == [(DeviceKind.DIGIT, "D30003"), (DeviceKind.DIGIT, "D30004"),
                     (DeviceKind.DIGIT_PROGRAMMING, "X"), (DeviceKind.GELSIGHT_MINI, "28J3-CWXU"),
                     (DeviceKind.DIGIT, None)]
    assert result.devices[0].firmware_revision == 201
    assert any("12 Mb/s" in p for p in result.devices[1].problems)
    locked = result.devices[4]
    assert locked.needs_udev_rule and "60-tactile-force.rules" in " ".join(locked.problems)


def test_bcd_revision():
    assert bcd_to_revision(0x0200) == 200 and bcd_to_revision(0x0105) == 105
    with pytest.raises(ValueError, match="0x01af"):
        bcd_to_revision(0x01AF)


def test_udev_rules_file_ships_with_package():
    text = udev_rules_path().read_text()
    for ids in ('"2833", ATTRS{idProduct}=="0209"', '"0403", ATTRS{idProduct}=="0fde"', '"0c45"', '"03e7"'):
        assert ids in text


def test_devices_command_with_no_hardware_says_so(tmp_path, capsys):
    empty = tmp_path / "sys"
    (empty / "bus" / "usb" / "devices").mkdir(parents=True)
    assert cli_main(["devices", "--sys-root", str(empty), "--dev-root", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "no DIGIT, GelSight Mini or OAK attached" in out


def test_devices_command_on_this_host_exits_zero(capsys):
    assert cli_main(["devices"]) == 0
    assert "USB devices" in capsys.readouterr().out


def test_devices_command_lists_problems(tree, capsys):
    assert cli_main(["devices", "--sys-root", str(tree[0]), "--dev-root", str(tree[1])]) == 0
    out = capsys.readouterr().out
    assert "D20001" in out and "fw rev 200" in out and "programming mode" in out and "2BNK-CEGG" in out
    assert cli_main(["devices", "--json", "--sys-root", str(tree[0]), "--dev-root", str(tree[1])]) == 0
    data = json.loads(capsys.readouterr().out)
    assert sorted(d["kind"] for d in data["devices"]) == ["digit", "digit", "digit-programming", "gelsight-mini"]


def test_default_discovery_prefers_udev_and_falls_back_to_sysfs(monkeypatch, tmp_path):
    import sys

    from tactile_force.firmware_bridge import discovery

    from .fake_udev import FakeCameraDevice, FakeUdevContext

    ctx = FakeUdevContext()
    ctx.plug(FakeCameraDevice("1-2", 0x2833, 0x0209, "D20001", "DIGIT", videos=[2, 3]), announce=False)
    monkeypatch.setattr(discovery, "udev_context", lambda: ctx)
    result = discover()
    assert result.method == "udev" and [d.serial for d in result.devices] == ["D20001"]
    tree = make_fake_sysfs(tmp_path, [FakeSysfsDevice("1-2", 0x2833, 0x0209, 0x0200, "D20001", videos=[(2, 0)])])
    assert discover(*tree).method == "sysfs"  # explicit roots: sysfs, not this host's libudev
    monkeypatch.setattr(discovery, "udev_context", lambda: None)  # libudev absent
    assert discover().method in ("sysfs", "pyusb", "none")
    monkeypatch.undo()
    monkeypatch.setitem(sys.modules, "pyudev", None)  # pyudev not installed
    assert discovery.udev_context() is None
