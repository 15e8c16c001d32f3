"""Find attached DIGIT / GelSight Mini / OAK devices and say what is wrong with them.

Linux: through libudev with pyudev (the ``usb`` extra, what digit-interface uses), or
straight from sysfs when pyudev or libudev is absent (no permission needed either way).
Elsewhere, or when sysfs has no USB tree: pyusb (the ``usb`` extra). :func:`classify`
turns a raw :class:`UsbDeviceInfo` into an :class:`AttachedDevice` with plain-language
problems. Hot-plug events (unplug / replug) come from :mod:`.hotplug`.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from tactile_force.edge.errors import SourceError, require

from .sysfs import UsbDeviceInfo, scan_sysfs, scan_udev
from .usb_ids import DIGIT_RGB_INTENSITY_MIN_REVISION, HIGH_SPEED_MBPS, DeviceKind, bcd_to_revision, classify_ids

#: The udev rules file shipped with the package, and where it goes.
UDEV_RULES_NAME = "60-tactile-force.rules"
UDEV_INSTALL_HINT = (
    "install the udev rule shipped with tactile-force, then replug the device:\n"
    "  sudo cp \"$(python -c 'import tactile_force.firmware_bridge as f; print(f.udev_rules_path())')\" "
    f"/etc/udev/rules.d/{UDEV_RULES_NAME}\n"
    "  sudo udevadm control --reload-rules && sudo udevadm trigger"
)

_DIGIT_SERIAL = re.compile(r"^D\d{5}$")
_PYUSB_SPEED_MBPS = {1: 1.5, 2: 12.0, 3: 480.0, 4: 5000.0, 5: 10000.0}


@dataclass(slots=True)
class AttachedDevice:
    """A classified device: kind, serial, firmware revision, nodes and problems.

    streamable: False for devices that must not be opened as cameras (programming mode,
    no video node); problems: one plain sentence each, empty when all is well.
    """

    kind: DeviceKind
    info: UsbDeviceInfo
    serial: str | None
    firmware_revision: int | None = None
    problems: list[str] = field(default_factory=list)
    streamable: bool = False

    @property
    def video_node(self) -> str | None:
        """The primary /dev/videoN capture node, or None."""
        return self.info.video_nodes[0] if self.info.video_nodes else None

    @property
    def needs_udev_rule(self) -> bool:
        return any("permission" in p for p in self.problems)

    def describe(self) -> str:
        """One line: kind, serial, ids, revision, speed, node."""
        i = self.info
        parts = [f"{self.kind.value:<17}", f"serial {self.serial or '?'}", f"{i.vendor_id:04x}:{i.product_id:04x}"]
        if self.firmware_revision is not None:
            parts.append(f"fw rev {self.firmware_revision}")
        if i.speed_mbps is not None:
            parts.append(f"{i.speed_mbps:g} Mb/s")
        if i.bus is not None:
            parts.append(f"bus {i.bus:03d} dev {i.address:03d}")
        parts.append(" ".join(i.video_nodes) if i.video_nodes else "no video node")
        return "  ".join(parts)


def _access_problem(path: str, what: str) -> str | None:
    if path and os.path.exists(path) and not os.access(path, os.R_OK | os.W_OK):
        return f"no read/write permission on {path} ({what}); {UDEV_INSTALL_HINT}"
    return None


def classify(info: UsbDeviceInfo) -> AttachedDevice:
    """Classify one USB device and list its problems (speed, mode, nodes, permissions)."""
    kind = classify_ids(info.vendor_id, info.product_id)
    dev = AttachedDevice(kind=kind, info=info, serial=info.serial)
    if info.read_problem:
        dev.problems.append(info.read_problem)
    if kind is DeviceKind.DIGIT:
        try:
            dev.firmware_revision = bcd_to_revision(info.bcd_device)
        except ValueError as exc:
            dev.problems.append(str(exc))
        if info.serial is not None and not _DIGIT_SERIAL.match(info.serial):
            dev.problems.append(f"serial {info.serial!r} does not look like a DIGIT serial (D + 5 digits)")
        if dev.firmware_revision is not None and dev.firmware_revision < DIGIT_RGB_INTENSITY_MIN_REVISION:
            dev.problems.append(f"firmware revision {dev.firmware_revision} < {DIGIT_RGB_INTENSITY_MIN_REVISION}: "
                                "LED intensity cannot be set per channel; update the DIGIT firmware")
    elif kind is DeviceKind.GELSIGHT_MINI:
        # The Mini's unit serial (e.g. 2BNK-CEGG) is the end of its product string.
        m = re.search(r"([A-Z0-9]{4}-[A-Z0-9]{4})\s*$", info.product)
        if m:
            dev.serial = m.group(1)
    elif kind is DeviceKind.DIGIT_PROGRAMMING:
        dev.problems.append("DIGIT in firmware-programming mode (FTDI 0403:0fde): it cannot stream; "
                            "finish or restart the firmware update, then replug it")
    if kind in (DeviceKind.DIGIT, DeviceKind.GELSIGHT_MINI):
        if info.speed_mbps is not None and info.speed_mbps < HIGH_SPEED_MBPS:
            dev.problems.append(f"bus speed {info.speed_mbps:g} Mb/s, needs {HIGH_SPEED_MBPS:g} (USB 2.0 high speed): "
                                "a charge-only or damaged cable, or a USB 1.1 port/hub; swap the cable or port")
        if not info.video_nodes:
            dev.problems.append("no /dev/video node: the uvcvideo driver is not bound (modprobe uvcvideo) "
                                "or the bus speed is too low for the camera")
        for node in info.video_nodes[:1]:
            if (p := _access_problem(node, "camera stream")):
                dev.problems.append(p)
        dev.streamable = bool(info.video_nodes) and not any("permission" in p for p in dev.problems)
    if kind is DeviceKind.OAK and (p := _access_problem(info.usb_node, "OAK over USB")):
        dev.problems.append(p)
    return dev


def scan_pyusb(find: Callable[..., Iterable] | None = None) -> list[UsbDeviceInfo]:
    """All USB devices via pyusb; ``find`` defaults to ``usb.core.find`` (tests pass fakes).

    A string descriptor that cannot be read (no permission) leaves serial None and records
    the reason in ``read_problem``.
    """
    if find is None:
        usb_core = require("usb.core", "usb", "USB discovery without sysfs")
        try:
            devices = list(usb_core.find(find_all=True))
        except usb_core.NoBackendError:
            raise SourceError("pyusb found no libusb backend; install libusb-1.0 "
                              "(Debian/Ubuntu: apt install libusb-1.0-0, macOS: brew install libusb)") from None
    else:
        devices = list(find(find_all=True))
    out: list[UsbDeviceInfo] = []
    for d in devices:
        problem, serial, product = "", None, ""
        if classify_ids(d.idVendor, d.idProduct) is not DeviceKind.OTHER:
            try:
                serial = d.serial_number
                product = d.product or ""
            except (ValueError, OSError, NotImplementedError) as exc:  # pyusb: USBError is an OSError
                problem = (f"cannot read the USB string descriptors of {d.idVendor:04x}:{d.idProduct:04x} "
                           f"({exc}): no permission on the device node; {UDEV_INSTALL_HINT}")
        out.append(UsbDeviceInfo(
            vendor_id=d.idVendor, product_id=d.idProduct, bcd_device=d.bcdDevice, serial=serial, product=product,
            speed_mbps=_PYUSB_SPEED_MBPS.get(getattr(d, "speed", 0) or 0), bus=d.bus, address=d.address,
            read_problem=problem))
    return out


@dataclass(slots=True)
class DiscoveryResult:
    """What :func:`discover` found: known devices, how it looked, and why it may have seen nothing."""

    devices: list[AttachedDevice]
    method: str  # 'udev' | 'sysfs' | 'pyusb' | 'none'
    note: str = ""

    def of_kind(self, *kinds: DeviceKind) -> list[AttachedDevice]:
        return [d for d in self.devices if d.kind in kinds]


def udev_context() -> Any | None:
    """A ``pyudev.Context``, or None when pyudev is not installed or libudev cannot be
    loaded (containers, non-Linux): callers then fall back to sysfs."""
    try:
        import pyudev
    except ImportError:
        return None
    try:
        return pyudev.Context()
    except (ImportError, OSError):  # pyudev raises ImportError when libudev.so is missing
        return None


_DEFAULT_ROOTS = ("/sys", "/dev")


def discover(sys_root: str | os.PathLike = "/sys", dev_root: str | os.PathLike = "/dev",
             find: Callable[..., Iterable] | None = None, context: Any | None = None) -> DiscoveryResult:
    """Find the DIGIT / GelSight Mini / OAK devices attached to this host (others are dropped).

    Order: libudev through ``context`` (default: pyudev's, when the default roots are used
    and libudev loads), then sysfs under ``sys_root``, then pyusb (``find``). Tests pass a
    fake ``context``, fake roots or a fake ``find``.
    """
    if context is None and find is None and (str(sys_root), str(dev_root)) == _DEFAULT_ROOTS:
        context = udev_context()
    if context is not None and find is None:
        infos, method, note = scan_udev(context), "udev", ""
    elif (Path(sys_root) / "bus" / "usb" / "devices").is_dir() and find is None:
        infos, method, note = scan_sysfs(sys_root, dev_root), "sysfs", ""
    else:
        try:
            infos, method, note = scan_pyusb(find), "pyusb", ""
        except (SourceError, ImportError) as exc:
            return DiscoveryResult([], "none", f"no USB bus visible: {Path(sys_root) / 'bus/usb/devices'} is absent "
                                               f"and pyusb cannot list devices ({exc})")
    devices = [classify(i) for i in infos if classify_ids(i.vendor_id, i.product_id) is not DeviceKind.OTHER]
    return DiscoveryResult(devices, method, note)


def _find_sensor(kind: DeviceKind, label: str, sensor: str | int, result: DiscoveryResult,
                 hint: str = "") -> AttachedDevice:
    """The attached ``kind`` named by serial or by index in serial order; SourceError listing
    what is attached when it is not there or cannot stream. ``hint`` is added to a miss."""
    found = result.of_kind(kind)
    listing = ", ".join(d.serial or "?" for d in found) or "none"
    if isinstance(sensor, int) or (isinstance(sensor, str) and sensor.isdigit()):
        idx = int(sensor)
        ordered = sorted(found, key=lambda d: d.serial or "")
        if not 0 <= idx < len(ordered):
            raise SourceError(f"{label} index {idx}: {len(ordered)} {label}(s) attached ({listing}); "
                              f"{result.note}".rstrip("; "))
        dev = ordered[idx]
    else:
        matches = [d for d in found if d.serial == sensor]
        if not matches:
            raise SourceError(f"{label} {sensor!r} not attached (attached {label}s: {listing}{hint}); "
                              f"{result.note}".rstrip("; "))
        dev = matches[0]
    if not dev.streamable:
        raise SourceError(f"{label} {dev.serial}: cannot stream: " + "; ".join(dev.problems))
    return dev


def find_digit(sensor: str | int, result: DiscoveryResult | None = None) -> AttachedDevice:
    """The DIGIT named by serial ('D12345') or by index among attached DIGITs (0, 1, ...).

    Raises SourceError listing what is attached when it is not there or cannot stream.
    """
    result = result or discover()
    prog = result.of_kind(DeviceKind.DIGIT_PROGRAMMING)
    hint = f"; {len(prog)} DIGIT(s) in programming mode" if prog else ""
    return _find_sensor(DeviceKind.DIGIT, "DIGIT", sensor, result, hint)


def find_gelsight_mini(sensor: str | int, result: DiscoveryResult | None = None) -> AttachedDevice:
    """The GelSight Mini named by serial ('2BNK-CEGG', the end of its USB product string) or
    by index among attached Minis (0, 1, ... in serial order).

    Raises SourceError listing what is attached when it is not there or cannot stream.
    """
    return _find_sensor(DeviceKind.GELSIGHT_MINI, "GelSight Mini", sensor, result or discover())


def locate_sensor(sensor: str | int, find: Callable[[str | int, DiscoveryResult], AttachedDevice],
                  roots: tuple = ()) -> tuple[AttachedDevice | None, str]:
    """(attached device or None, /dev/videoN) for a sensor named by serial, index or a
    '/dev/...' path. ``find`` is :func:`find_digit` or :func:`find_gelsight_mini`; ``roots``
    are the (sys_root, dev_root) passed to :func:`discover`. A path is used as given (the
    device record is attached when discovery sees it); a serial or index must be found."""
    result = discover(*roots)
    if isinstance(sensor, str) and sensor.startswith("/dev/"):
        return next((d for d in result.devices if sensor in d.info.video_nodes), None), sensor
    dev = find(sensor, result)
    return dev, dev.video_node  # type: ignore[return-value]


def udev_rules_path() -> Path:
    """Path of the udev rules file shipped inside the package."""
    return Path(__file__).with_name("udev") / UDEV_RULES_NAME
