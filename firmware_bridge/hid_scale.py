"""A USB point-of-sale scale (HID usage page 0x8D) as a reference force sensor.

Data report layout (HID Point of Sale Usage Tables, weighing devices), bytes:

    [report id 3] status  unit  exponent(int8)  weight (uint16 little-endian, or 4 bytes)

status is the Scale Status selector (1 fault, 2 stable at centre of zero, 3 in motion,
4 weight stable, 5 under zero, 6 over weight limit, 7 requires calibration, 8 requires
re-zeroing); unit the Weight Unit selector (1 mg, 2 g, 3 kg, 4 carat, 5 tael, 6 grain,
7 pennyweight, 8 metric ton, 9 avoir ton, 10 troy ounce, 11 ounce, 12 pound);
weight * 10**exponent is the mass in that unit. Under zero the magnitude is reported
positive (a two's-complement value is accepted too). Force = mass_kg * 9.80665 N.
"""

from __future__ import annotations

import enum
import time
from dataclasses import dataclass, field
from typing import Protocol

from tactile_force.edge.errors import SourceError, TactileForceError, require

#: Standard gravity, m/s^2 (force in N = mass in kg * G).
G = 9.80665
#: HID usage page of point-of-sale scales.
SCALE_USAGE_PAGE = 0x8D
DATA_REPORT_ID = 3


class ScaleReportError(TactileForceError, ValueError):
    """A HID report is too short, has an unknown unit, or is not a scale data report."""


class ScaleStatus(enum.IntEnum):
    """HID POS Scale Status selector values."""

    FAULT = 1
    ZERO = 2  #: stable at centre of zero
    IN_MOTION = 3
    STABLE = 4
    UNDER_ZERO = 5
    OVERLOAD = 6  #: over weight limit
    NEEDS_CALIBRATION = 7
    NEEDS_REZERO = 8


#: Weight Unit selector -> (name, kilograms per unit).
UNITS: dict[int, tuple[str, float]] = {
    1: ("mg", 1e-6),
    2: ("g", 1e-3),
    3: ("kg", 1.0),
    4: ("ct", 2e-4),
    5: ("tael", 0.0377994),  # Hong Kong tael
    6: ("gr", 64.79891e-6),
    7: ("dwt", 1.55517384e-3),
    8: ("t", 1000.0),
    9: ("ton", 907.18474),
    10: ("ozt", 31.1034768e-3),
    11: ("oz", 28.349523125e-3),
    12: ("lb", 0.45359237),
}

#: Statuses whose weight is a usable reference.
_VALID = (ScaleStatus.ZERO, ScaleStatus.STABLE, ScaleStatus.UNDER_ZERO, ScaleStatus.IN_MOTION)


@dataclass(slots=True)
class ScaleReading:
    """One decoded scale report.

    force_n: weight force in N (negative under zero; tare offset subtracted; nan when the
    status carries no weight); mass_kg: the same as mass; stable: status ZERO or STABLE;
    valid: the value can serve as ground truth (not fault / overload / needing calibration).
    """

    status: ScaleStatus
    unit: str
    value: float  #: in ``unit``
    mass_kg: float
    force_n: float
    stable: bool
    valid: bool
    timestamp_ns: int = 0
    raw: bytes = b""


def parse_scale_report(report: bytes | bytearray | list[int], has_report_id: bool = True,
                       timestamp_ns: int = 0, tare_n: float = 0.0) -> ScaleReading:
    """Decode one HID scale data report into newtons.

    ``has_report_id``: the first byte is the report id (hidapi on Linux returns it for
    devices with numbered reports). ``tare_n`` is subtracted from the force.
    Raises :class:`ScaleReportError` naming the bytes on anything unexpected.
    """
    raw = bytes(report)
    body = raw
    if has_report_id:
        if not raw or raw[0] != DATA_REPORT_ID:
            raise ScaleReportError(f"HID report {raw.hex(' ')}: report id {raw[0] if raw else None}, "
                                   f"expected the scale data report id {DATA_REPORT_ID}")
        body = raw[1:]
    if len(body) < 5:
        raise ScaleReportError(f"HID report {raw.hex(' ')}: {len(body)} data bytes, expected >= 5 "
                               "(status, unit, exponent, weight lo, weight hi)")
    try:
        status = ScaleStatus(body[0])
    except ValueError:
        raise ScaleReportError(f"HID report {raw.hex(' ')}: scale status {body[0]} not in 1..8") from None
    unit_code, exponent = body[1], int.from_bytes(body[2:3], "little", signed=True)
    width = 4 if len(body) >= 7 else 2
    magnitude = int.from_bytes(body[3:3 + width], "little", signed=False)
    if status is ScaleStatus.UNDER_ZERO:
        if magnitude >> (8 * width - 1):  # two's complement negative
            magnitude -= 1 << (8 * width)
        magnitude = -abs(magnitude)
    if status in (ScaleStatus.FAULT, ScaleStatus.OVERLOAD, ScaleStatus.NEEDS_CALIBRATION, ScaleStatus.NEEDS_REZERO):
        nan = float("nan")
        unit = UNITS.get(unit_code, (f"unit#{unit_code}", nan))[0]
        return ScaleReading(status, unit, nan, nan, nan, False, False, timestamp_ns, raw)
    if unit_code not in UNITS:
        raise ScaleReportError(f"HID report {raw.hex(' ')}: weight unit {unit_code} not in 1..12 "
                               "(HID POS weight units)")
    unit, kg_per_unit = UNITS[unit_code]
    value = magnitude * 10.0 ** exponent
    mass = value * kg_per_unit
    stable = status in (ScaleStatus.ZERO, ScaleStatus.STABLE)
    return ScaleReading(status, unit, value, mass, mass * G - tare_n, stable, status in _VALID, timestamp_ns, raw)


@dataclass(slots=True)
class ScaleOptions:
    """Which scale to open and how to read it.

    vendor_id/product_id: None = the first HID device on usage page 0x8D;
    read_timeout_ms: how long :meth:`HidScale.read` waits for a report.
    """

    vendor_id: int | None = None
    product_id: int | None = None
    has_report_id: bool = True
    read_timeout_ms: int = 200
    report_size: int = 64


def find_scales(enumerate_fn=None) -> list[dict]:
    """HID devices on the scale usage page (dicts as hidapi's ``hid.enumerate`` gives)."""
    if enumerate_fn is None:
        enumerate_fn = require("hid", "usb", "the HID reference scale").enumerate
    return [d for d in enumerate_fn() if d.get("usage_page") == SCALE_USAGE_PAGE]


class HidDevice(Protocol):
    """What HidScale uses of a hidapi device (real or a test fake)."""

    def read(self, size: int, timeout_ms: int = 0) -> list[int]: ...


@dataclass
class HidScale:
    """An open HID scale: ``read()`` -> latest :class:`ScaleReading`; ``tare()`` zeroes it.

    Build with :meth:`open`; tests pass a fake hidapi device object (``read(size, timeout_ms)``
    returning a list of ints, empty on timeout).
    """

    device: HidDevice
    options: ScaleOptions = field(default_factory=ScaleOptions)
    name: str = "scale"
    tare_n: float = 0.0
    last: ScaleReading | None = None

    @classmethod
    def open(cls, options: ScaleOptions | None = None) -> HidScale:
        """Open the scale named by ``options`` (or the first one found)."""
        options = options or ScaleOptions()
        hid = require("hid", "usb", "the HID reference scale")
        scales = find_scales(hid.enumerate)
        if options.vendor_id is not None:
            scales = [d for d in scales if d["vendor_id"] == options.vendor_id
                      and (options.product_id is None or d["product_id"] == options.product_id)]
        if not scales:
            raise SourceError("no USB scale found (no HID device on usage page 0x8D"
                              + (f" with id {options.vendor_id:04x}" if options.vendor_id is not None else "")
                              + "); plug in a HID point-of-sale scale or check the udev rule for /dev/hidraw*")
        info = scales[0]
        dev = hid.device()
        try:
            dev.open_path(info["path"])
        except OSError as exc:
            raise SourceError(f"cannot open scale {info['vendor_id']:04x}:{info['product_id']:04x} at "
                              f"{info['path']!r} ({exc}): no permission on /dev/hidraw*? install the udev rule "
                              "(tactile-force devices prints how)") from None
        name = (info.get("product_string") or "scale").strip()
        return cls(dev, options, name)

    def read(self) -> ScaleReading | None:
        """Drain pending reports and return the newest one, or the last known if none arrived.

        Returns None when the scale never reported within the timeout; raises SourceError
        when the device is gone (unplugged).
        """
        newest = None
        timeout = self.options.read_timeout_ms
        while True:
            try:
                data = self.device.read(self.options.report_size, timeout)
            except (OSError, ValueError) as exc:
                raise SourceError(f"scale {self.name}: read failed ({exc}); unplugged?") from None
            if not data:
                break
            try:
                newest = parse_scale_report(data, self.options.has_report_id, time.monotonic_ns(), self.tare_n)
            except ScaleReportError:
                if self.options.has_report_id and data and data[0] != DATA_REPORT_ID:
                    continue  # another report (status/attributes): not a weight
                raise
            timeout = 0  # only wait for the first; then drain what is queued
        if newest is not None:
            self.last = newest
        return self.last

    def tare(self) -> float:
        """Take the current force as zero (host side); returns the offset in N."""
        self.tare_n = 0.0
        reading = self.read()
        if reading is None or not reading.stable:
            raise SourceError(f"scale {self.name}: cannot tare: no stable reading "
                              f"({'none' if reading is None else reading.status.name.lower()})")
        self.tare_n = reading.mass_kg * G
        return self.tare_n

    def close(self) -> None:
        close = getattr(self.device, "close", None)
        if close:
            close()
