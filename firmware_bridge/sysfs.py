"""Read attached USB devices and their /dev/videoN nodes: through libudev (pyudev) or,
where libudev is absent, straight from Linux sysfs.

Both are world-readable, so this works without the udev rule: vendor/product ids, serial
string, bcdDevice, bus speed (Mb/s) and the V4L2 capture nodes of a UVC device.
:func:`scan_udev` takes the pyudev context (tests pass a fake); :func:`scan_sysfs` takes
the roots (tests point them at a fake tree).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


@dataclass(slots=True)
class UsbDeviceInfo:
    """One USB device as read from sysfs or pyusb.

    speed_mbps: negotiated bus speed in Mb/s (1.5, 12, 480, 5000, ...; None if unknown);
    video_nodes: /dev/videoN paths of its V4L2 capture interfaces, primary first;
    usb_node: /dev/bus/usb/BBB/DDD (needed for a USB reset);
    serial: None when it could not be read (pyusb without permission).
    """

    vendor_id: int
    product_id: int
    bcd_device: int
    serial: str | None
    product: str = ""
    manufacturer: str = ""
    speed_mbps: float | None = None
    bus: int | None = None
    address: int | None = None
    sysfs_path: str = ""
    usb_node: str = ""
    video_nodes: list[str] = field(default_factory=list)
    read_problem: str = ""  # why a descriptor could not be read (permissions), empty if fine


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def _hex(path: Path) -> int | None:
    text = _read(path)
    try:
        return int(text, 16) if text else None
    except ValueError:
        return None


def _int(path: Path) -> int | None:
    text = _read(path)
    try:
        return int(text) if text else None
    except ValueError:
        return None


def video_nodes_by_usb_device(sys_root: str | os.PathLike = "/sys",
                              dev_root: str | os.PathLike = "/dev") -> dict[str, list[str]]:
    """Map the real sysfs path of each USB device to its /dev/videoN nodes.

    A UVC camera exposes a capture node (sysfs ``index`` 0) and often a metadata node
    (index 1); capture nodes come first, then by number.
    """
    cls = Path(sys_root) / "class" / "video4linux"
    found: dict[str, list[tuple[int, int, str]]] = {}
    if not cls.is_dir():
        return {}
    for entry in cls.iterdir():
        if not entry.name.startswith("video"):
            continue
        try:
            number = int(entry.name[5:])
        except ValueError:
            continue
        real = Path(os.path.realpath(entry))
        # Walk up from .../1-2/1-2:1.0/video4linux/videoN to the USB device (has idVendor).
        parent = real.parent
        while parent != parent.parent and not (parent / "idVendor").is_file():
            parent = parent.parent
        if not (parent / "idVendor").is_file():
            continue
        index = _int(entry / "index")
        found.setdefault(str(parent), []).append((index if index is not None else 0, number,
                                                  str(Path(dev_root) / entry.name)))
    return {k: [node for _, _, node in sorted(v)] for k, v in found.items()}


def scan_sysfs(sys_root: str | os.PathLike = "/sys", dev_root: str | os.PathLike = "/dev") -> list[UsbDeviceInfo]:
    """All USB devices under ``sys_root``/bus/usb/devices (interfaces and hubs' ports skipped)."""
    base = Path(sys_root) / "bus" / "usb" / "devices"
    if not base.is_dir():
        return []
    videos = video_nodes_by_usb_device(sys_root, dev_root)
    devices: list[UsbDeviceInfo] = []
    for entry in sorted(base.iterdir()):
        if ":" in entry.name:  # an interface (1-2:1.0), not a device
            continue
        vid, pid = _hex(entry / "idVendor"), _hex(entry / "idProduct")
        if vid is None or pid is None:
            continue
        real = os.path.realpath(entry)
        bus, addr = _int(entry / "busnum"), _int(entry / "devnum")
        speed = _read(entry / "speed")
        try:
            speed_mbps = float(speed) if speed else None
        except ValueError:
            speed_mbps = None
        devices.append(UsbDeviceInfo(
            vendor_id=vid, product_id=pid, bcd_device=_hex(entry / "bcdDevice") or 0,
            serial=_read(entry / "serial"), product=_read(entry / "product") or "",
            manufacturer=_read(entry / "manufacturer") or "", speed_mbps=speed_mbps, bus=bus, address=addr,
            sysfs_path=real,
            usb_node=str(Path(dev_root) / "bus" / "usb" / f"{bus:03d}" / f"{addr:03d}") if bus and addr else "",
            video_nodes=videos.get(real, []),
        ))
    return devices


# -- libudev (pyudev) ------------------------------------------------------------------------
def _attr(device: Any, name: str) -> str | None:
    """A sysfs attribute of a pyudev Device as text, None when absent or unreadable."""
    try:
        value = device.attributes.asstring(name)
    except (KeyError, OSError, UnicodeDecodeError):
        return None
    return value.strip() if value is not None else None


def _attr_num(device: Any, name: str, base: int) -> int | None:
    text = _attr(device, name)
    try:
        return int(text, base) if text else None
    except ValueError:
        return None


def udev_video_nodes(context: Any) -> dict[str, list[str]]:
    """Map the sys_path of each USB device to its /dev/videoN nodes (capture node, sysfs
    ``index`` 0, first), from libudev's video4linux devices."""
    found: dict[str, list[tuple[int, str]]] = {}
    for v in context.list_devices(subsystem="video4linux"):
        node = v.device_node
        parent = v.find_parent("usb", "usb_device")
        if not node or parent is None:
            continue
        index = _attr_num(v, "index", 10)
        found.setdefault(parent.sys_path, []).append((index if index is not None else 0, node))
    return {k: [node for _, node in sorted(v, key=lambda t: (t[0], _video_number(t[1])))] for k, v in found.items()}


def _video_number(node: str) -> int:
    digits = "".join(c for c in Path(node).name if c.isdigit())
    return int(digits) if digits else 0


def udev_usb_info(device: Any, video_nodes: list[str] | None = None) -> UsbDeviceInfo | None:
    """A pyudev ``usb_device`` as :class:`UsbDeviceInfo`; None when it has no USB ids."""
    vid, pid = _attr_num(device, "idVendor", 16), _attr_num(device, "idProduct", 16)
    if vid is None or pid is None:
        return None
    speed = _attr(device, "speed")
    try:
        speed_mbps = float(speed) if speed else None
    except ValueError:
        speed_mbps = None
    return UsbDeviceInfo(
        vendor_id=vid, product_id=pid, bcd_device=_attr_num(device, "bcdDevice", 16) or 0,
        serial=_attr(device, "serial"), product=_attr(device, "product") or "",
        manufacturer=_attr(device, "manufacturer") or "", speed_mbps=speed_mbps,
        bus=_attr_num(device, "busnum", 10), address=_attr_num(device, "devnum", 10),
        sysfs_path=device.sys_path, usb_node=device.device_node or "", video_nodes=list(video_nodes or []))


def scan_udev(context: Any) -> list[UsbDeviceInfo]:
    """All USB devices libudev knows (``context``: a ``pyudev.Context`` or a fake with
    ``list_devices``), with their video nodes, in sys_path order."""
    videos = udev_video_nodes(context)
    out = []
    for d in sorted(context.list_devices(subsystem="usb", DEVTYPE="usb_device"), key=lambda d: d.sys_path):
        info = udev_usb_info(d, videos.get(d.sys_path))
        if info is not None:
            out.append(info)
    return out
