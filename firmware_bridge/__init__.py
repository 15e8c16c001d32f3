"""tactile_force.firmware_bridge: USB sensors, HID reference scale, OAK accelerator.

Importing this package imports none of pyusb, hidapi or depthai: each is imported inside
the function that needs it and a missing one raises MissingExtraError naming the extra
(``usb`` for pyusb/hidapi, ``oak`` for depthai).
"""

from .digit import RESOLUTIONS, DigitOptions, DigitSource, intensity_code, reset_usb_device
from .discovery import (
                        AttachedDevice,
                        DiscoveryResult,
                        classify,
                        discover,
                        find_digit,
                        find_gelsight_mini,
                        scan_pyusb,
                        udev_rules_path,
)
from .gelsight import SDK_CROP_FRACTION, GelSightMiniOptions, GelSightMiniSource, crop_box
from .hid_scale import (
                        G,
                        HidScale,
                        ScaleOptions,
                        ScaleReading,
                        ScaleReportError,
                        ScaleStatus,
                        find_scales,
                        parse_scale_report,
)
from .nn_archive import NNArchiveInfo, archive_config, build_nn_archive
from .oak import OakForceModel, OakOptions, available_oaks
from .recorder import RecordOptions, RecordResult, prepare_output, record
from .sysfs import UsbDeviceInfo, scan_sysfs
from .usb_ids import DeviceKind, bcd_to_revision, classify_ids

__all__ = [
    "AttachedDevice", "DeviceKind", "DigitOptions", "DigitSource", "DiscoveryResult", "G", "GelSightMiniOptions",
    "GelSightMiniSource", "HidScale", "NNArchiveInfo", "OakForceModel", "OakOptions", "RESOLUTIONS",
    "RecordOptions", "RecordResult", "SDK_CROP_FRACTION", "ScaleOptions", "ScaleReading", "ScaleReportError",
    "ScaleStatus", "UsbDeviceInfo", "archive_config", "available_oaks", "bcd_to_revision", "build_nn_archive",
    "classify", "classify_ids", "crop_box", "discover", "find_digit", "find_gelsight_mini", "find_scales",
    "intensity_code", "parse_scale_report", "prepare_output", "record", "reset_usb_device", "scan_pyusb",
    "scan_sysfs", "udev_rules_path",
]
