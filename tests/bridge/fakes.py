"""Fakes at the hardware boundary only: USB device objects, sysfs trees, HID devices,
V4L2 cameras and the depthai device/queue layer. Everything above them is the real code."""

from __future__ import annotations

import os
import time
import types
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np


# -- USB (pyusb-like device objects) ---------------------------------------------------------
@dataclass
class FakeUsbDevice:
    """Looks like a pyusb ``usb.core.Device``; ``no_permission`` makes string reads fail as pyusb does."""

    idVendor: int
    idProduct: int
    bcdDevice: int = 0x0100
    serial: str | None = None
    product_name: str = ""
    speed: int = 3  # usb.util.SPEED_HIGH
    bus: int = 1
    address: int = 2
    no_permission: bool = False
    resets: int = 0

    @property
    def serial_number(self) -> str | None:
        if self.no_permission:
            raise ValueError("The device has no langid (permission issue, no string descriptors supported or device error)")
        return self.serial

    @property
    def product(self) -> str:
        if self.no_permission:
            raise ValueError("The device has no langid")
        return self.product_name

    def reset(self) -> None:
        self.resets += 1


def fake_find(devices: list[FakeUsbDevice]):
    """A ``usb.core.find`` over fake devices (find_all / custom_match only)."""

    def find(find_all: bool = False, custom_match=None, **_):
        hits = [d for d in devices if custom_match is None or custom_match(d)]
        return hits if find_all else (hits[0] if hits else None)

    return find


# -- sysfs trees -------------------------------------------------------------------------------
@dataclass
class FakeSysfsDevice:
    port: str  # e.g. '1-2'
    vendor_id: int
    product_id: int
    bcd_device: int = 0x0200
    serial: str | None = None
    product: str = ""
    speed: str = "480"
    busnum: int = 1
    devnum: int = 5
    videos: list[tuple[int, int]] = field(default_factory=list)  # (N of /dev/videoN, sysfs index)


def make_fake_sysfs(root: Path, devices: list[FakeSysfsDevice]) -> tuple[Path, Path]:
    """Build a sysfs-shaped tree (real symlinks, as the kernel lays it out) and a /dev folder."""
    sys_root, dev_root = root / "sys", root / "dev"
    bus_dir = sys_root / "bus" / "usb" / "devices"
    cls_dir = sys_root / "class" / "video4linux"
    for d in (bus_dir, cls_dir, dev_root):
        d.mkdir(parents=True, exist_ok=True)
    hub = sys_root / "devices" / "pci0000:00" / "0000:00:14.0" / "usb1"
    hub.mkdir(parents=True, exist_ok=True)
    for name, value in (("idVendor", "1d6b"), ("idProduct", "0002"), ("bcdDevice", "0515"), ("speed", "480"),
                        ("busnum", "1"), ("devnum", "1")):
        (hub / name).write_text(value + "\n")
    (bus_dir / "usb1").symlink_to(os.path.relpath(hub, bus_dir))
    for dev in devices:
        d = hub / dev.port
        d.mkdir(parents=True)
        attrs = {"idVendor": f"{dev.vendor_id:04x}", "idProduct": f"{dev.product_id:04x}",
                 "bcdDevice": f"{dev.bcd_device:04x}", "speed": dev.speed, "busnum": str(dev.busnum),
                 "devnum": str(dev.devnum), "product": dev.product}
        if dev.serial is not None:
            attrs["serial"] = dev.serial
        for name, value in attrs.items():
            (d / name).write_text(value + "\n")
        iface = d / f"{dev.port}:1.0"
        iface.mkdir()
        (iface / "bInterfaceClass").write_text("0e\n")
        (bus_dir / dev.port).symlink_to(os.path.relpath(d, bus_dir))
        (bus_dir / iface.name).symlink_to(os.path.relpath(iface, bus_dir))
        for number, index in dev.videos:
            v = iface / "video4linux" / f"video{number}"
            v.mkdir(parents=True)
            (v / "index").write_text(f"{index}\n")
            (cls_dir / f"video{number}").symlink_to(os.path.relpath(v, cls_dir))
            (dev_root / f"video{number}").write_text("")
        usb_node = dev_root / "bus" / "usb" / f"{dev.busnum:03d}"
        usb_node.mkdir(parents=True, exist_ok=True)
        (usb_node / f"{dev.devnum:03d}").write_text("")
    return sys_root, dev_root


# -- HID scale --------------------------------------------------------------------------------
class FakeHidDevice:
    """A hidapi ``hid.device`` with one new report pending per poll: ``read(size, timeout_ms)``
    returns the next scripted report (list of ints), then [] (queue drained) on the following
    read; when the script is used up it keeps re-sending the last report, as a scale does.
    After ``unplug_after`` reports, reads raise OSError like a vanished /dev/hidraw."""

    def __init__(self, reports: list[list[int]], unplug_after: int | None = None) -> None:
        self.reports = list(reports)
        self.unplug_after = unplug_after
        self.sent = 0
        self._last: list[int] = []
        self._pending = True

    def read(self, size: int, timeout_ms: int = 0) -> list[int]:
        if not self._pending:
            self._pending = True
            return []
        if self.unplug_after is not None and self.sent >= self.unplug_after:
            raise OSError("read error")
        if self.reports:
            self._last = self.reports.pop(0)
        self._pending = False
        self.sent += 1
        return self._last[:size]

    def close(self) -> None:
        pass


# -- V4L2 camera --------------------------------------------------------------------------------
class FakeCamera:
    """A cv2.VideoCapture over a list of frames; ``fail_after`` reads then returns (False, None).
    ``formats``: the fourcc codes it accepts (None: any); ``period_s``: each read waits this long,
    like a camera streaming at 1/period_s fps; ``size``: the (width, height) the driver settles
    on whatever was asked (None: what was asked)."""

    def __init__(self, frames: list[np.ndarray], fail_after: int | None = None, opened: bool = True,
                 formats: tuple[str, ...] | None = None, period_s: float = 0.0,
                 size: tuple[int, int] | None = None) -> None:
        self.frames = frames
        self.size = size
        self.fail_after = fail_after
        self.opened = opened
        self.formats = formats
        self.period_s = period_s
        self.props: dict[int, float] = {}
        self.reads = 0
        self.released = False

    def isOpened(self) -> bool:
        return self.opened

    def set(self, prop: int, value: float) -> bool:
        if prop == cv2.CAP_PROP_FOURCC and self.formats is not None and \
                value not in [cv2.VideoWriter_fourcc(*f) for f in self.formats]:
            return False
        self.props[prop] = value
        return True

    def get(self, prop: int) -> float:
        if self.size is not None and prop in (cv2.CAP_PROP_FRAME_WIDTH, cv2.CAP_PROP_FRAME_HEIGHT):
            return float(self.size[0] if prop == cv2.CAP_PROP_FRAME_WIDTH else self.size[1])
        return float(self.props.get(prop, 0.0))

    def read(self):
        if self.released:
            return False, None
        if self.period_s:
            time.sleep(self.period_s)
        self.reads += 1
        if self.fail_after is not None and self.reads > self.fail_after:
            return False, None
        return True, self.frames[(self.reads - 1) % len(self.frames)].copy()

    def release(self) -> None:
        self.released = True


# -- depthai --------------------------------------------------------------------------------------
def fake_depthai(devices: list[str], model=lambda img: float(img.mean())) -> types.SimpleNamespace:
    """A stand-in for the ``depthai`` module: device search, Device, Pipeline, a NeuralNetwork node
    whose queues run ``model`` on the host. ``calls`` records which constructors ran."""
    calls: list[str] = []

    class DeviceInfo:
        def __init__(self, did: str) -> None:
            self.did = did
            self.name = did

        def getDeviceId(self) -> str:
            return self.did

    class Device:
        @staticmethod
        def getAllAvailableDevices():
            calls.append("getAllAvailableDevices")
            return [DeviceInfo(d) for d in devices]

        def __init__(self, *args) -> None:
            calls.append("Device")

        def close(self) -> None:
            calls.append("Device.close")

    class ImgFrame:
        Type = types.SimpleNamespace(BGR888i="BGR888i", BGR888p="BGR888p", GRAY8="GRAY8")

        def setCvFrame(self, array, type_):
            self.array, self.type = np.array(array), type_
            return self

        def setSequenceNum(self, n):
            self.seq = n

    class NNData:
        def __init__(self, value: float) -> None:
            self.value = value

        def hasLayer(self, name):
            return name == "force"

        def getTensor(self, name, *a):
            return np.array([[self.value]], np.float32)

        def getFirstTensor(self, *a):
            return np.array([[self.value]], np.float32)

    class Queue:
        def __init__(self) -> None:
            self.items: list = []

        def send(self, msg):
            self.items.append(NNData(model(msg.array)))

        def get(self, timeout=None):
            return self.items.pop(0) if self.items else None

    class NeuralNetwork:
        def __init__(self) -> None:
            q = Queue()
            self.input = types.SimpleNamespace(createInputQueue=lambda: q)
            self.out = types.SimpleNamespace(createOutputQueue=lambda: q)

        def setNNArchive(self, archive):
            calls.append("setNNArchive")

    class Pipeline:
        def __init__(self, *args, **kwargs) -> None:
            calls.append("Pipeline")

        def create(self, cls):
            return cls()

        def start(self):
            calls.append("start")

        def stop(self):
            calls.append("stop")

    return types.SimpleNamespace(__version__="fake", Device=Device, Pipeline=Pipeline, ImgFrame=ImgFrame,
                                 NNArchive=lambda path: calls.append("NNArchive") or path,
                                 node=types.SimpleNamespace(NeuralNetwork=NeuralNetwork), calls=calls)


def landscape(portrait):
    """What the camera streams: the inverse of digit-interface's transpose + flip(0)."""
    return np.ascontiguousarray(cv2.transpose(cv2.flip(portrait, 0)))
