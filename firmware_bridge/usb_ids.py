"""USB identities of the devices this package talks to, and how to read their descriptors.

Vendor/product ids are 16-bit integers; ``bcdDevice`` is binary-coded decimal.
"""

from __future__ import annotations

import enum


class DeviceKind(str, enum.Enum):
    """What an attached USB device is, as far as this package is concerned."""

    DIGIT = "digit"  #: a DIGIT streaming as a UVC camera
    DIGIT_PROGRAMMING = "digit-programming"  #: a DIGIT in firmware-programming mode (FTDI); cannot stream
    GELSIGHT_MINI = "gelsight-mini"  #: a GelSight Mini UVC camera
    OAK = "oak"  #: a Luxonis OAK (Movidius VPU, booted or not)
    OTHER = "other"


#: (idVendor, idProduct) -> kind.
KNOWN_IDS: dict[tuple[int, int], DeviceKind] = {
    (0x2833, 0x0209): DeviceKind.DIGIT,
    (0x0403, 0x0FDE): DeviceKind.DIGIT_PROGRAMMING,
    (0x0C45, 0x636D): DeviceKind.GELSIGHT_MINI,
    (0x03E7, 0x2485): DeviceKind.OAK,  # RVC2 MyriadX, not booted
    (0x03E7, 0xF63B): DeviceKind.OAK,  # RVC2, booted (XLink)
    (0x03E7, 0xF63C): DeviceKind.OAK,  # RVC2 bootloader
}

DIGIT_ID = (0x2833, 0x0209)
#: USB 2.0 high speed, Mb/s; a DIGIT below it is on a charge-only/bad cable or a USB 1.1 port.
HIGH_SPEED_MBPS = 480.0
#: The first DIGIT firmware revision whose LEDs take per-channel (r, g, b) intensity.
DIGIT_RGB_INTENSITY_MIN_REVISION = 200


def classify_ids(vendor_id: int, product_id: int) -> DeviceKind:
    """Kind of a device from its (idVendor, idProduct)."""
    return KNOWN_IDS.get((vendor_id, product_id), DeviceKind.OTHER)


def bcd_to_revision(bcd_device: int) -> int:
    """Firmware revision from ``bcdDevice`` read as decimal digits: 0x0200 -> 200.

    This is how digit-interface reports it (udev's ID_REVISION '0200' read as an int).
    Raises ValueError naming the value when a nibble is not a decimal digit.
    """
    text = f"{bcd_device:04x}"
    if not text.isdigit():
        raise ValueError(f"bcdDevice 0x{text}: not binary-coded decimal (each hex digit must be 0..9)")
    return int(text)
