"""Unplug and replug of a DIGIT through the pyudev path: udev events from a fake libudev
(tests/bridge/fake_udev.py) and fake V4L2 cameras at the hardware boundary; the real
UdevWatcher, HotplugSource, CameraSource, ContactGate, ONNX Runtime model and ForceRuntime
above them. The unplugged sensor is dropped and comes back at its new /dev/videoN; the
other sensor is served all along."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import pytest
from tactile_force.edge.errors import SourceError
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.reading import Flags
from tactile_force.edge.runtime import ForceRuntime, Sensor
from tactile_force.edge.sources import CameraSource, load_background
from tactile_force.firmware_bridge import DeviceKind, discover
from tactile_force.firmware_bridge.hotplug import HotplugSource, UdevWatcher

from tests.conftest import shared_data

from .fake_udev import FakeCameraDevice, FakeUdevContext
from .fakes import FakeCamera

DEFAULT_BUNDLE = Path(__file__).resolve().parents[2] / "edge" / "models" / "default"


def _digit(port: str, serial: str, devnum: int, videos: list[int]) -> FakeCameraDevice:
    return FakeCameraDevice(port, 0x2833, 0x0209, serial, "DIGIT", devnum=devnum, videos=videos)


class Cameras:
    """open_capture for CameraSource: a FakeCamera per /dev/videoN opened, streaming the real
    frames; a node the fake udev does not list cannot be opened (the device is gone)."""

    def __init__(self, frames, udev: FakeUdevContext) -> None:
        self.frames = frames
        self.udev = udev
        self.opened: dict[str, FakeCamera] = {}
        self.order: list[str] = []

    def __call__(self, node):
        present = any(d.device_node == node for d in self.udev.list_devices(subsystem="video4linux"))
        cam = FakeCamera(self.frames, period_s=0.01, opened=present)
        self.opened[node] = cam
        self.order.append(node)
        return cam


@pytest.fixture
def udev():
    ctx = FakeUdevContext()
    ctx.plug(_digit("1-2", "D20001", 5, [2, 3]), announce=False)
    ctx.plug(_digit("1-3", "D20002", 6, [4, 5]), announce=False)
    ctx.plug(FakeCameraDevice("1-4", 0x046D, 0x0825, "ABC", "Webcam", devnum=8, videos=[8]), announce=False)
    return ctx


def _open(cams: Cameras):
    return lambda dev: CameraSource(dev.video_node, fourcc=(), max_failures=1, grab_thread=False,
                                    open_capture=cams, name=dev.serial or "digit")


def test_discovery_through_udev_classifies_and_finds_nodes(udev):
    result = discover(context=udev)
    assert result.method == "udev"
    assert [(d.kind, d.serial, d.video_node) for d in result.devices] == [
        (DeviceKind.DIGIT, "D20001", "/dev/video2"), (DeviceKind.DIGIT, "D20002", "/dev/video4")]
    assert result.devices[0].info.video_nodes == ["/dev/video2", "/dev/video3"]
    assert result.devices[0].info.usb_node == "/dev/bus/usb/001/005" and result.devices[0].firmware_revision == 200


def test_watcher_follows_remove_and_add_events(udev):
    w = UdevWatcher(udev, udev.monitor)
    assert udev.monitor.started and w.find(DeviceKind.DIGIT, "D20001").video_node == "/dev/video2"
    udev.unplug("1-2")
    ev = w.poll(1.0)
    assert (ev.action, ev.device.serial) == ("remove", "D20001") and w.find(DeviceKind.DIGIT, "D20001") is None
    assert w.poll(0.05) is None  # the interface and USB-device removals of the same DIGIT say nothing new
    udev.plug(_digit("1-2", "D20001", 9, [6, 7]))
    got = w.wait_for(DeviceKind.DIGIT, "D20001", timeout_s=2.0)
    assert got is not None and got.video_node == "/dev/video6" and got.info.usb_node.endswith("001/009")
    udev.unplug("1-4")  # not ours: no event
    assert w.poll(0.05) is None


def _gate() -> ContactGate:
    g = ContactGate()
    g.capture_background(load_background(shared_data("digit_backgrounds", "aurova_background_b.png")))
    return g


def test_unplug_and_replug_of_one_digit_while_the_other_is_served(udev, portraits):
    watcher = UdevWatcher(udev, udev.monitor)
    cams = Cameras(portraits, udev)
    left = HotplugSource(DeviceKind.DIGIT, "D20001", _open(cams), watcher, name="left")
    right = HotplugSource(DeviceKind.DIGIT, "D20002", _open(cams), watcher, name="right")
    rt = ForceRuntime([Sensor("left", left, _gate()), Sensor("right", right, _gate())],
                      OnnxForceModel(DEFAULT_BUNDLE), )
    readings = {"left": [], "right": []}

    def run_until(cond, timeout_s=30.0):
        end = time.monotonic() + timeout_s
        while not cond():
            assert time.monotonic() < end, f"timed out: left {len(readings['left'])}, right {len(readings['right'])}"
            for r in rt.step():
                readings[r.sensor].append(r)

    try:
        run_until(lambda: len(readings["left"]) >= 3 and len(readings["right"]) >= 3)
        udev.unplug("1-2")
        cams.opened["/dev/video2"].release()  # the capture fails once the device is gone
        run_until(lambda: left.state == "waiting for replug")
        n_left = len(readings["left"])
        n_right = len(readings["right"])
        run_until(lambda: len(readings["right"]) >= n_right + 15)
        assert len(readings["left"]) <= n_left + 1  # at most the frame a grabber held before the unplug
        assert left.state == "waiting for replug" and watcher.find(DeviceKind.DIGIT, "D20001") is None
        dropped_at = len(readings["left"])

        udev.plug(_digit("1-2", "D20001", 9, [6, 7]))  # back, at a new node
        run_until(lambda: len(readings["left"]) >= dropped_at + 5)
    finally:
        rt.close()
    assert cams.order == ["/dev/video2", "/dev/video4", "/dev/video6"]
    assert left.nodes == ["/dev/video2", "/dev/video6"] and left.replugs == 1 and right.replugs == 0
    assert all(s.alive for s in rt.sensors) and rt.stats.source_errors == 0
    idx = [r.frame_index for r in readings["left"]]
    assert idx == sorted(set(idx))  # frame indices continue across the replug
    served = readings["right"]
    assert len(served) >= n_right + 15 and not any(r.flags & Flags.INVALID_INPUT for r in served)
    assert all(r.flags & Flags.NO_CONTACT or r.force_n == r.force_n for r in readings["left"] + served)


def test_not_back_in_time_is_a_source_error(udev, portraits):
    watcher = UdevWatcher(udev, udev.monitor)
    cams = Cameras(portraits, udev)
    src = HotplugSource(DeviceKind.DIGIT, "D20001", _open(cams), watcher, replug_timeout_s=0.3)
    assert src.read().index == 0
    udev.unplug("1-2")
    cams.opened["/dev/video2"].release()
    with pytest.raises(SourceError, match=r"D20001: unplugged .* not back within 0.3 s"):
        src.read()
    with pytest.raises(SourceError, match="closed"):
        src.read()


def test_close_ends_a_wait_for_replug(udev, portraits):
    watcher = UdevWatcher(udev, udev.monitor)
    cams = Cameras(portraits, udev)
    src = HotplugSource(DeviceKind.DIGIT, "D20001", _open(cams), watcher)
    src.read()
    udev.unplug("1-2")
    cams.opened["/dev/video2"].release()
    errors = []
    t = threading.Thread(target=lambda: errors.append(pytest.raises(SourceError, src.read)))
    t.start()
    end = time.monotonic() + 5
    while src.state != "waiting for replug" and time.monotonic() < end:
        time.sleep(0.01)
    src.close()
    t.join(timeout=2.0)
    assert not t.is_alive() and errors and "closed" in str(errors[0].value)


def test_unknown_serial_and_kind_are_refused(udev):
    watcher = UdevWatcher(udev, udev.monitor)
    with pytest.raises(SourceError, match=r"'D99999': not attached .*digit D20001"):
        HotplugSource(DeviceKind.DIGIT, "D99999", lambda d: None, watcher)
    with pytest.raises(ValueError, match="expected a camera"):
        HotplugSource(DeviceKind.OAK, "X", lambda d: None, watcher)


def test_digit_hotplug_source_opens_digit_source_by_serial_or_index(udev, portraits, tmp_path):
    from tactile_force.firmware_bridge.digit import DigitOptions
    from tactile_force.firmware_bridge.hotplug import digit_hotplug_source

    watcher = UdevWatcher(udev, udev.monitor)
    cams = Cameras(portraits, udev)
    empty = tmp_path / "sys" / "bus" / "usb" / "devices"
    empty.mkdir(parents=True)  # DigitSource's own lookup of a /dev path: nothing to attach
    src = digit_hotplug_source(DigitOptions(1), watcher, open_capture=cams, sys_root=tmp_path / "sys",
                               dev_root=tmp_path)
    assert src.serial == "D20002" and src.nodes == ["/dev/video4"] and src._inner.options.reconnect_attempts == 0
    assert src.read().frame.shape == (320, 240, 3)
    udev.unplug("1-3")
    cams.opened["/dev/video4"].release()
    udev.plug(_digit("1-3", "D20002", 10, [9]))
    assert src.read().index == 1 and src.nodes == ["/dev/video4", "/dev/video9"]
    src.close()
    with pytest.raises(SourceError, match="not by /dev path"):
        digit_hotplug_source(DigitOptions("/dev/video2"), watcher)
