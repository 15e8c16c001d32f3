"""Read attached USB devices and their /dev/videoN nodes from Linux sysfs (no pyudev).

sysfs is world-readable, so this works without the udev rule: vendor/product ids, serial
string, bcdDevice, bus speed (Mb/s) and the V4L2 capture nodes of a UVC device. Roots are
parameters so tests can point them at a fake tree.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path


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
