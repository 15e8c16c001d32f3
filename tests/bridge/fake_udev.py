"""A fake libudev at the hardware boundary: FakeUdevContext / FakeUdevMonitor / FakeUdevDevice
answer the pyudev calls the discovery and hot-plug code makes (list_devices, find_parent,
attributes.asstring, Monitor.poll), and FakeUdevContext.plug / unplug play the events the
kernel sends when a USB camera is plugged in or pulled out. Everything above is the real code."""

from __future__ import annotations

import queue
from dataclasses import dataclass, field


class FakeUdevAttributes:
    def __init__(self, values: dict[str, str]) -> None:
        self._values = values

    def asstring(self, name: str) -> str:
        if name not in self._values:
            raise KeyError(name)
        return self._values[name]


@dataclass
class FakeUdevDevice:
    """A pyudev.Device: sys_path, subsystem, device_type, device_node, attributes, action."""

    sys_path: str
    subsystem: str
    device_type: str | None = None
    device_node: str | None = None
    attrs: dict[str, str] = field(default_factory=dict)
    parent: FakeUdevDevice | None = None
    action: str | None = None

    @property
    def attributes(self) -> FakeUdevAttributes:
        return FakeUdevAttributes(self.attrs)

    def find_parent(self, subsystem: str, device_type: str | None = None) -> FakeUdevDevice | None:
        p = self.parent
        while p is not None:
            if p.subsystem == subsystem and (device_type is None or p.device_type == device_type):
                return p
            p = p.parent
        return None

    def event(self, action: str) -> FakeUdevDevice:
        """This device as a monitor reports it for ``action`` (a copy carrying the action)."""
        return FakeUdevDevice(self.sys_path, self.subsystem, self.device_type, self.device_node, dict(self.attrs),
                              self.parent, action)


@dataclass
class FakeCameraDevice:
    """What to plug: a USB camera with its ids, serial and /dev/videoN numbers (capture node first)."""

    port: str
    vendor_id: int
    product_id: int
    serial: str | None
    product: str = ""
    bcd_device: int = 0x0200
    speed: str = "480"
    busnum: int = 1
    devnum: int = 5
    videos: list[int] = field(default_factory=list)


class FakeUdevMonitor:
    """A pyudev.Monitor: ``start``, ``filter_by`` (recorded) and ``poll(timeout)`` over a queue."""

    def __init__(self) -> None:
        self.events: queue.Queue[FakeUdevDevice] = queue.Queue()
        self.filters: list[tuple[str, str | None]] = []
        self.started = False

    def filter_by(self, subsystem: str, device_type: str | None = None) -> None:
        self.filters.append((subsystem, device_type))

    def start(self) -> None:
        self.started = True

    def poll(self, timeout: float | None = None) -> FakeUdevDevice | None:
        try:
            return self.events.get(timeout=timeout)
        except queue.Empty:
            return None


class FakeUdevContext:
    """A pyudev.Context over a table of fake devices; ``plug`` / ``unplug`` change the table
    and queue the udev events on ``monitor`` in the kernel's order (USB device, interface,
    video nodes on add; the reverse on remove)."""

    ROOT = "/sys/devices/pci0000:00/0000:00:14.0/usb1"

    def __init__(self) -> None:
        self.devices: list[FakeUdevDevice] = []
        self.monitor = FakeUdevMonitor()

    def list_devices(self, subsystem: str | None = None, DEVTYPE: str | None = None, **_) -> list[FakeUdevDevice]:  # noqa: N803
        return [d for d in self.devices if (subsystem is None or d.subsystem == subsystem)
                and (DEVTYPE is None or d.device_type == DEVTYPE)]

    def plug(self, cam: FakeCameraDevice, announce: bool = True) -> list[FakeUdevDevice]:
        usb = FakeUdevDevice(f"{self.ROOT}/{cam.port}", "usb", "usb_device",
                             f"/dev/bus/usb/{cam.busnum:03d}/{cam.devnum:03d}",
                             {"idVendor": f"{cam.vendor_id:04x}", "idProduct": f"{cam.product_id:04x}",
                              "bcdDevice": f"{cam.bcd_device:04x}", "speed": cam.speed, "busnum": str(cam.busnum),
                              "devnum": str(cam.devnum), "product": cam.product,
                              **({"serial": cam.serial} if cam.serial is not None else {})})
        iface = FakeUdevDevice(f"{usb.sys_path}/{cam.port}:1.0", "usb", "usb_interface", parent=usb)
        added = [usb, iface]
        for i, n in enumerate(cam.videos):
            added.append(FakeUdevDevice(f"{iface.sys_path}/video4linux/video{n}", "video4linux",
                                        device_node=f"/dev/video{n}", attrs={"index": str(i)}, parent=iface))
        self.devices += added
        if announce:
            for d in added:
                self.monitor.events.put(d.event("add"))
        return added

    def unplug(self, port: str) -> None:
        path = f"{self.ROOT}/{port}"
        gone = [d for d in self.devices if d.sys_path == path or d.sys_path.startswith(path + "/")]
        self.devices = [d for d in self.devices if d not in gone]
        for d in reversed(gone):
            self.monitor.events.put(d.event("remove"))
