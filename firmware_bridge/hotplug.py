"""USB hot-plug through libudev events (pyudev, the ``usb`` extra): unplug and replug of a
DIGIT or GelSight Mini arrive as events, not by polling.

:class:`UdevWatcher` keeps the set of attached devices up to date from a udev monitor
(``usb`` and ``video4linux`` subsystems). :class:`HotplugSource` wraps a camera source:
when the device stops delivering it closes it, waits for the udev ``add`` event of the
same serial (blocking on the monitor, not rescanning) and reopens at the new
/dev/videoN, frame indices continuing. In a two-sensor runtime each sensor is read in its
own thread, so the other finger keeps being served while one waits for its replug.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from tactile_force.edge.errors import SourceError, require
from tactile_force.edge.frames import FrameSource, TimedFrame

from .discovery import AttachedDevice, classify
from .sysfs import scan_udev, udev_usb_info, udev_video_nodes
from .usb_ids import DeviceKind, classify_ids

log = logging.getLogger(__name__)

#: How long one wait on the monitor lasts before checking for close() (seconds).
POLL_SLICE_S = 0.25


@dataclass(frozen=True, slots=True)
class HotplugEvent:
    """A device came ('add') or went ('remove'); ``device`` as classified (for a removal:
    as it was last seen)."""

    action: str
    device: AttachedDevice


class UdevWatcher:
    """Attached DIGIT / GelSight Mini / OAK devices, kept current by udev events.

    Parameters
    ----------
    context : pyudev.Context, optional
        Default: a new one (needs pyudev and libudev). Tests pass a fake.
    monitor : pyudev.Monitor, optional
        Default: ``Monitor.from_netlink(context)`` filtered to ``usb`` and ``video4linux``.
    """

    def __init__(self, context: Any | None = None, monitor: Any | None = None) -> None:
        if context is None or monitor is None:
            pyudev = require("pyudev", "usb", "USB hot-plug events")
        try:
            if context is None:
                context = pyudev.Context()
            if monitor is None:
                monitor = pyudev.Monitor.from_netlink(context)
                monitor.filter_by("usb", "usb_device")
                monitor.filter_by("video4linux")
            monitor.start()  # subscribe before enumerating: no event between the two is lost
        except (ImportError, OSError) as exc:  # libudev missing, or no netlink socket (container)
            raise SourceError(f"USB hot-plug: cannot listen to udev events ({exc}); "
                              "run without hot-plug, or on a host with udev") from None
        self.context = context
        self.monitor = monitor
        self._lock = threading.Lock()
        self.present: dict[str, AttachedDevice] = {}
        for info in scan_udev(context):
            if classify_ids(info.vendor_id, info.product_id) is not DeviceKind.OTHER:
                self.present[info.sysfs_path] = classify(info)

    # -- events ----------------------------------------------------------------------------------
    def _usb_parent(self, device: Any) -> Any | None:
        if device.subsystem == "usb" and device.device_type == "usb_device":
            return device
        try:
            return device.find_parent("usb", "usb_device")
        except (LookupError, OSError, ValueError):
            return None

    def _owner(self, sys_path: str) -> str | None:
        """The tracked USB device a (removed) sys_path belongs to."""
        for path in self.present:
            if sys_path == path or sys_path.startswith(path + "/"):
                return path
        return None

    def handle(self, device: Any) -> HotplugEvent | None:
        """Update the device set from one udev event; the event it means for a known device
        kind, or None (other devices, 'change'/'bind' actions)."""
        action = device.action
        with self._lock:
            if action == "remove":
                path = self._owner(device.sys_path)
                if path is None:
                    return None
                # The first of its removals (a video node or the USB device) ends the device.
                return HotplugEvent("remove", self.present.pop(path))
            if action != "add":
                return None
            parent = self._usb_parent(device)
            if parent is None:
                return None
            videos = udev_video_nodes(self.context).get(parent.sys_path, [])
            info = udev_usb_info(parent, videos)
            if info is None or classify_ids(info.vendor_id, info.product_id) is DeviceKind.OTHER:
                return None
            dev = classify(info)
            known = self.present.get(parent.sys_path)
            self.present[parent.sys_path] = dev
            if known is not None and known.info.video_nodes == dev.info.video_nodes:
                return None  # another interface of a device already announced
            return HotplugEvent("add", dev)

    def poll(self, timeout_s: float | None = None) -> HotplugEvent | None:
        """Wait up to ``timeout_s`` for the next udev event about a known device kind."""
        end = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            left = None if end is None else max(0.0, end - time.monotonic())
            device = self.monitor.poll(timeout=left)
            if device is None:
                return None
            event = self.handle(device)
            if event is not None:
                return event
            if end is not None and time.monotonic() >= end:
                return None

    # -- lookups -----------------------------------------------------------------------------------
    def find(self, kind: DeviceKind, serial: str) -> AttachedDevice | None:
        """The attached, streamable device of ``kind`` with ``serial``, or None."""
        with self._lock:
            return next((d for d in self.present.values()
                         if d.kind is kind and d.serial == serial and d.streamable), None)

    def wait_for(self, kind: DeviceKind, serial: str, timeout_s: float | None = None,
                 stop: threading.Event | None = None) -> AttachedDevice | None:
        """Block until the device of ``kind`` with ``serial`` is attached and streamable
        (at once when it already is); None after ``timeout_s`` seconds or when ``stop`` is set."""
        end = None if timeout_s is None else time.monotonic() + timeout_s
        while self.poll(0.0) is not None:  # take in what already happened (a removal not yet seen)
            pass
        while True:
            dev = self.find(kind, serial)
            if dev is not None:
                return dev
            if stop is not None and stop.is_set():
                return None
            left = POLL_SLICE_S if end is None else min(POLL_SLICE_S, end - time.monotonic())
            if left <= 0:
                return None
            self.poll(left)


class HotplugSource(FrameSource):
    """A camera source that survives unplug and replug of its device, driven by udev events.

    Parameters
    ----------
    kind : DeviceKind
        DIGIT or GELSIGHT_MINI.
    serial : str
        The device's serial ('D20001', '2BNK-CEGG').
    open_source : callable
        ``open_source(device) -> FrameSource`` opens the camera of an attached device (e.g. a
        DigitSource or CameraSource at ``device.video_node``).
    watcher : UdevWatcher
        The event source (one per process is enough; sensors may share it).
    replug_timeout_s : float, optional
        Give up (SourceError, the runtime then drops the sensor) when the device is not back
        within this many seconds; None waits until :meth:`close`.

    While the device is away ``read()`` blocks; ``state`` says 'streaming', 'waiting for
    replug' or 'closed', ``replugs`` counts the reopenings, ``nodes`` lists the video nodes
    opened in turn.
    """

    def __init__(self, kind: DeviceKind, serial: str, open_source: Callable[[AttachedDevice], FrameSource],
                 watcher: UdevWatcher, replug_timeout_s: float | None = None, name: str | None = None) -> None:
        super().__init__()
        if kind not in (DeviceKind.DIGIT, DeviceKind.GELSIGHT_MINI):
            raise ValueError(f"hot-plug source kind {kind.value!r}: expected a camera (digit or gelsight-mini)")
        if replug_timeout_s is not None and not replug_timeout_s > 0:
            raise ValueError(f"replug_timeout_s={replug_timeout_s!r}: expected seconds > 0 or None")
        self.kind = kind
        self.serial = serial
        self.name = name or serial
        self.watcher = watcher
        self.replug_timeout_s = replug_timeout_s
        self._open_source = open_source
        self._stop = threading.Event()
        self.replugs = 0
        self.nodes: list[str] = []
        self._offset = 0  # frame index where the current inner source started
        self._next_index = 0
        dev = watcher.find(kind, serial)
        if dev is None:
            listing = ", ".join(f"{d.kind.value} {d.serial}" for d in watcher.present.values()) or "none"
            raise SourceError(f"{kind.value} {serial!r}: not attached or cannot stream (attached: {listing})")
        self._inner: FrameSource | None = self._open(dev)
        self.state = "streaming"

    def _open(self, dev: AttachedDevice) -> FrameSource:
        src = self._open_source(dev)
        self.nodes.append(dev.video_node or "")
        return src

    def read(self) -> TimedFrame | None:
        """Next frame; blocks through an unplug until the device is back. SourceError when
        it is not back within ``replug_timeout_s`` or the source was closed."""
        while True:
            inner = self._inner
            if inner is None or self._stop.is_set():
                raise SourceError(f"{self.kind.value} {self.serial}: source is closed")
            try:
                tf = inner.read()
            except SourceError as exc:
                self._replug(str(exc))
                continue
            if tf is None:
                return None
            tf.index += self._offset
            self._next_index = tf.index + 1
            tf.meta.setdefault("sensor", self.name)
            self.stats.frames += 1
            return tf

    def _replug(self, reason: str) -> None:
        """Close the dead stream and wait for the device's udev 'add' event."""
        self.state = "waiting for replug"
        inner, self._inner = self._inner, None
        if inner is not None:
            self.stats.dropped += inner.stats.dropped
            self.stats.corrupt += inner.stats.corrupt
            inner.close()
        log.warning("%s %s: %s; waiting for it to be plugged in again", self.kind.value, self.serial, reason)
        dev = self.watcher.wait_for(self.kind, self.serial, self.replug_timeout_s, self._stop)
        if self._stop.is_set():
            self.state = "closed"
            raise SourceError(f"{self.kind.value} {self.serial}: source is closed")
        if dev is None:
            self.state = "closed"
            raise SourceError(f"{self.kind.value} {self.serial}: unplugged ({reason}) and not back within "
                              f"{self.replug_timeout_s:g} s")
        self._inner = self._open(dev)
        self._offset = self._next_index
        self.replugs += 1
        self.state = "streaming"
        log.warning("%s %s: back at %s", self.kind.value, self.serial, dev.video_node)

    def close(self) -> None:
        """Stop waiting and close the camera; safe to call twice."""
        self._stop.set()
        inner, self._inner = self._inner, None
        if inner is not None:
            inner.close()
        self.state = "closed"


def digit_hotplug_source(options: Any, watcher: UdevWatcher | None = None, *,
                         replug_timeout_s: float | None = None, name: str | None = None,
                         **digit_kwargs: Any) -> HotplugSource:
    """A DIGIT that survives unplug/replug: :class:`HotplugSource` over
    :class:`~tactile_force.firmware_bridge.digit.DigitSource` opened at the DIGIT's video node.

    ``options`` is a DigitOptions whose ``sensor`` is a serial or an index among attached
    DIGITs (resolved to the serial once, here); the DigitSource's own reconnect loop is
    turned off (the udev events take its place). ``digit_kwargs`` go to DigitSource
    (open_capture, sys_root, dev_root in tests).
    """
    from dataclasses import replace

    from .digit import DigitSource

    watcher = watcher or UdevWatcher()
    sensor = options.sensor
    if isinstance(sensor, int) or (isinstance(sensor, str) and sensor.isdigit()):
        digits = sorted((d for d in watcher.present.values() if d.kind is DeviceKind.DIGIT),
                        key=lambda d: d.serial or "")
        if not 0 <= int(sensor) < len(digits):
            raise SourceError(f"DIGIT index {sensor}: {len(digits)} DIGIT(s) attached")
        sensor = digits[int(sensor)].serial
    if not isinstance(sensor, str) or sensor.startswith("/dev/") or not sensor:
        raise SourceError(f"DIGIT {options.sensor!r}: hot-plug follows a DIGIT by serial (D12345) or index, "
                          "not by /dev path (the node changes on replug)")

    def open_digit(dev: AttachedDevice) -> FrameSource:
        return DigitSource(replace(options, sensor=dev.video_node, reconnect_attempts=0), **digit_kwargs)

    return HotplugSource(DeviceKind.DIGIT, sensor, open_digit, watcher, replug_timeout_s, name or sensor)
