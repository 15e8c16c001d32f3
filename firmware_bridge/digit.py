"""DIGIT as a frame source: find it by serial, configure it, survive it disappearing.

Capture itself (opening through V4L2, size/fps, orientation, VGA halving, corrupt-frame
counting) is :class:`~tactile_force.edge.sources.CameraSource`; this module adds what is
DIGIT-specific: serial lookup through sysfs, LED intensity, reconnect policy, USB reset.

Frames come out in the package convention: HxWx3 uint8 BGR, portrait 320 rows x 240
columns (the camera's landscape image transposed and flipped as digit-interface does;
VGA is then halved). Settings follow digit-interface: QVGA 320x240 at 60/30 fps, VGA
640x480 at 30/15 fps; LED intensity through the V4L2 zoom control as
(r << 8) | (g << 4) | b, channels 0..15, firmware revision >= 200 only.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np
from tactile_force.edge.errors import SourceError, require
from tactile_force.edge.frames import TimedFrame
from tactile_force.edge.sources import MAX_CORRUPT_IN_ROW, CameraSource, Capture, StreamLost, open_v4l2

from .discovery import AttachedDevice, discover, find_digit, locate_sensor
from .sysfs import UsbDeviceInfo
from .usb_ids import DIGIT_RGB_INTENSITY_MIN_REVISION

log = logging.getLogger(__name__)

#: name -> (width, height, allowed fps), landscape as the camera streams.
RESOLUTIONS: dict[str, tuple[int, int, tuple[int, ...]]] = {
    "QVGA": (320, 240, (60, 30)),
    "VGA": (640, 480, (30, 15)),
}


@dataclass
class DigitOptions:
    """How to open a DIGIT.

    sensor: serial ('D12345'), index among attached DIGITs (0, 1, ...) or a /dev/videoN path;
    intensity: LED (r, g, b), each 0..15, or None to keep the firmware's setting;
    reconnect_attempts/backoff_s/backoff_max_s: after a failed read, reopen up to this many
    times, waiting backoff_s, doubling, capped at backoff_max_s (seconds);
    usb_reset: before the last attempt, reset the device through pyusb (needs the udev rule).
    """

    sensor: str | int = 0
    resolution: str = "QVGA"
    fps: int = 60
    intensity: tuple[int, int, int] | None = None
    reconnect_attempts: int = 6
    backoff_s: float = 0.1
    backoff_max_s: float = 2.0
    usb_reset: bool = True

    def validate(self) -> None:
        if self.resolution not in RESOLUTIONS:
            raise ValueError(f"DIGIT resolution {self.resolution!r}: expected one of {sorted(RESOLUTIONS)}")
        rates = RESOLUTIONS[self.resolution][2]
        if self.fps not in rates:
            raise ValueError(f"DIGIT fps {self.fps} at {self.resolution}: expected one of {rates}")
        if self.intensity is not None:
            if len(self.intensity) != 3 or not all(isinstance(c, (int, np.integer)) and 0 <= c <= 15
                                                   for c in self.intensity):
                raise ValueError(f"DIGIT LED intensity {self.intensity!r}: expected (r, g, b) integers 0..15")
        if self.reconnect_attempts < 0 or self.backoff_s < 0:
            raise ValueError("DIGIT reconnect_attempts and backoff_s must be >= 0")


def intensity_code(r: int, g: int, b: int) -> int:
    """The zoom-control value that sets the DIGIT LEDs: (r << 8) | (g << 4) | b."""
    return ((r & 0x0F) << 8) | ((g & 0x0F) << 4) | (b & 0x0F)


def reset_usb_device(info: UsbDeviceInfo, find: Callable | None = None) -> None:
    """USB port reset of the device at (bus, address) through pyusb; SourceError if impossible."""
    if info.bus is None or info.address is None:
        raise SourceError("USB reset: bus/address of the device unknown")
    if find is None:
        find = require("usb.core", "usb", "the DIGIT USB reset").find
    try:
        dev = find(custom_match=lambda d: d.bus == info.bus and d.address == info.address)
        if dev is None:
            raise SourceError(f"USB reset: no device at bus {info.bus:03d} address {info.address:03d} (unplugged?)")
        dev.reset()
    except SourceError:
        raise
    except Exception as exc:  # pyusb raises USBError/NoBackendError, both environment problems
        raise SourceError(f"USB reset of bus {info.bus:03d} device {info.address:03d} failed ({exc}); "
                          "write access to /dev/bus/usb needs the udev rule (tactile-force devices)") from None


class DigitSource(CameraSource):
    """Frames from one DIGIT; reconnects with backoff when the stream dies.

    A :class:`~tactile_force.edge.sources.CameraSource` reading in the caller's thread
    (every frame returned, ``meta['sensor']`` = name), opened at the DIGIT's video node.
    ``open_capture(node)`` returns a cv2.VideoCapture-like object (tests pass a fake
    camera); ``sys_root``/``dev_root`` locate sysfs and /dev (tests pass fake trees).
    ``attached`` is the discovered device (serial, firmware revision, USB bus/address),
    None when a /dev path was given that discovery does not know; ``node`` is its
    /dev/videoN. read() blocks while reconnecting, so give each sensor its own thread:
    the other finger keeps being served. SourceError after the last failed attempt.
    """

    def __init__(self, options: DigitOptions | None = None, *, open_capture: Callable[[str], Capture] | None = None,
                 sys_root: str | os.PathLike = "/sys", dev_root: str | os.PathLike = "/dev",
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.options = options or DigitOptions()
        self.options.validate()
        self._roots = (sys_root, dev_root)
        self._sleep = sleep
        self.reconnects = 0
        self.usb_resets = 0
        self._attempts = 0  # reconnect attempts since the last good frame
        self.attached: AttachedDevice | None = None
        node = self._locate()
        name = (self.attached.serial if self.attached and self.attached.serial else node) or "digit"
        if self.options.intensity is not None:
            rev = self.attached.firmware_revision if self.attached else None
            if rev is None or rev < DIGIT_RGB_INTENSITY_MIN_REVISION:
                raise SourceError(f"DIGIT at {node}: firmware revision {rev if rev is not None else 'unknown'} "
                                  f"cannot take an RGB LED intensity (needs >= {DIGIT_RGB_INTENSITY_MIN_REVISION}); "
                                  "update the firmware or leave intensity unset")
        w, h, _ = RESOLUTIONS[self.options.resolution]
        super().__init__(node, fps=self.options.fps, fourcc=(), max_failures=1, max_corrupt=MAX_CORRUPT_IN_ROW,
                         name=name, size=(w, h), grab_thread=False, open_capture=open_capture or open_v4l2,
                         configure=self._set_leds)

    @property
    def node(self) -> str:
        """The /dev/videoN the DIGIT streams on (may change after a replug)."""
        return str(self.device)

    # -- device lookup and configuration ------------------------------------------------
    def _locate(self) -> str:
        self.attached, node = locate_sensor(self.options.sensor, find_digit, self._roots)
        return node

    def _set_leds(self, cap: Capture) -> None:
        """CameraSource configure hook: LED intensity through the V4L2 zoom control."""
        if self.options.intensity is not None:
            cap.set(cv2.CAP_PROP_ZOOM, intensity_code(*self.options.intensity))

    # -- reading ---------------------------------------------------------------------------
    def read(self) -> TimedFrame:
        """Next frame (never None: a camera stream has no end); SourceError when it cannot come back."""
        while True:
            try:
                item = super().read()
            except StreamLost as exc:
                self._reconnect(str(exc))
                continue
            self._attempts = 0
            item.meta["sensor"] = self.name
            return item

    def _reconnect(self, reason: str) -> None:
        """Reopen the stream with backoff. Attempts count until a good frame arrives, so a
        device that opens but never delivers still ends in SourceError."""
        self.close()
        opts, last = self.options, ""
        log.warning("DIGIT %s: %s; reconnecting", self.name, reason)
        while self._attempts < opts.reconnect_attempts:
            self._attempts += 1
            delay = min(opts.backoff_s * 2 ** (self._attempts - 1), opts.backoff_max_s)
            self._sleep(delay)
            self.reconnects += 1
            if self._attempts == opts.reconnect_attempts and opts.usb_reset and self.attached is not None:
                try:  # last resort
                    reset_usb_device(self.attached.info)
                    self.usb_resets += 1
                except (SourceError, ImportError) as exc:
                    last = str(exc)
                    log.warning("DIGIT %s: %s", self.name, exc)
            try:
                node = None
                if self.attached is not None:  # the node number can change after a replug
                    node = find_digit(self.attached.serial or opts.sensor, discover(*self._roots)).video_node
                self.reopen(node)
                log.warning("DIGIT %s: reopened after attempt %d", self.name, self._attempts)
                return
            except SourceError as exc:
                last = str(exc)
        raise SourceError(f"DIGIT {self.name}: stream lost ({reason}) and {opts.reconnect_attempts} reconnect "
                          f"attempts failed; last error: {last or 'reopened but no good frame'}")
