"""The source-kind registry: each kind's keys, gate preset, opener and one-line description.

A kind's keys are a dataclass (a :class:`~.model.SensorKeys` subclass) read by the typed
reader; adding a kind means adding its keys class and one :data:`SOURCE_KINDS` entry."""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from ..errors import SceneError, SourceError
from ..gate.options import GateOptions
from ..limits import FPS, GRASPS, SEED, as_metadata
from ..typed_json import check
from .model import Clock, SensorKeys, SensorSpec


# -- source kinds ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SourceKind:
    """One kind of frame source: its own keys (beyond name, source, background, gate), its
    gate preset, how to open it and one line saying what it is."""

    name: str
    keys: type[SensorKeys]
    gate_preset: Callable[[], GateOptions]
    opener: Callable[[SensorSpec, Clock], Any]
    describe: Callable[[SensorSpec], str]
    live: bool = True

    @property
    def key_names(self) -> list[str]:
        """The kind's own keys (beyond those of every sensor), in declaration order."""
        common = {f.name for f in dataclasses.fields(SensorKeys)}
        return [f.name for f in dataclasses.fields(self.keys) if f.name not in common]


_FPS = as_metadata(FPS)
_DEVICE = check(ge=0, expected="a camera index or a /dev/videoN path")


@dataclass(kw_only=True)
class CameraKeys(SensorKeys):
    """``camera``: device (index or /dev/videoN), fps (frames per second)."""

    device: int | str = field(default=0, metadata=_DEVICE)
    fps: float = field(default=60.0, metadata=_FPS)


@dataclass(kw_only=True)
class DigitKeys(SensorKeys):
    """``digit``: serial (or an index among attached DIGITs), fps (60 or 30 per second),
    hotplug (follow unplug / replug through udev events)."""

    serial: str | int = field(metadata=check(
        ge=0, expected="a DIGIT serial such as 'D20001', or an index among attached DIGITs"))
    fps: Literal[60, 30] = field(default=60, metadata=check(expected="60 or 30 (QVGA frame rates of a DIGIT)"))
    hotplug: bool = field(default=True, metadata=check(
        expected="true or false (follow unplug / replug through udev events)"))


@dataclass(kw_only=True)
class GelSightMiniKeys(SensorKeys):
    """``gelsight_mini``: device (serial, index or /dev/videoN), fps (frames per second)."""

    device: int | str = field(default=0, metadata=check(
        ge=0, expected="a GelSight Mini serial, an index or a /dev/videoN path"))
    fps: float = field(default=25.0, metadata=_FPS)


@dataclass(kw_only=True)
class ReplayKeys(SensorKeys):
    """``replay``: path (a replay folder, relative to the scene file), fps (None: as fast as read)."""

    path: Path = field(metadata=check(expected="a replay folder (images/N.png [+ forces/force_N.txt])"))
    fps: float | None = field(default=None, metadata=_FPS)


@dataclass(kw_only=True)
class VideoKeys(SensorKeys):
    """``video``: path (a video file, relative to the scene file), fps (None: as fast as read)."""

    path: Path = field(metadata=check(expected="a video file"))
    fps: float | None = field(default=None, metadata=_FPS)


@dataclass(kw_only=True)
class VirtualKeys(SensorKeys):
    """``virtual``: seed, n_grasps (grasps played, >= 1), fps (frames per second)."""

    seed: int = field(default=0, metadata=as_metadata(SEED))
    n_grasps: int = field(default=3, metadata=check(
        ge=GRASPS.ge, le=GRASPS.le, expected="an integer in [1, 10000] (grasps the virtual DIGIT plays)"))
    fps: float = field(default=60.0, metadata=_FPS)


def _open_camera(s: SensorSpec, clock: Clock):
    from ..sources import CameraSource

    return CameraSource(s.device, fps=s.fps or 60.0, name=s.name, clock=clock)


_udev_state: dict[str, Any] = {}


def udev_watcher():
    """The process's one UdevWatcher (pyudev + libudev), or None when hot-plug events cannot
    be had here (no pyudev, no libudev, no netlink socket); logged once, then cached."""
    if "watcher" not in _udev_state:
        try:
            from tactile_force.firmware_bridge.hotplug import UdevWatcher

            _udev_state["watcher"] = UdevWatcher()
        except (ImportError, SourceError) as exc:
            _udev_state["watcher"] = None
            logging.getLogger(__name__).warning(
                "USB hot-plug unavailable (%s): DIGITs are opened without it (an unplugged DIGIT is "
                "retried by its own reconnect loop, not followed by udev events)", exc)
    return _udev_state["watcher"]


def _open_digit(s: SensorSpec, clock: Clock):
    """A DIGIT by serial (or index): the serial is resolved to its /dev/videoN by the
    firmware_bridge discovery; SourceError naming the serial and listing attached DIGITs.

    With ``hotplug`` (default) and pyudev / libudev available, the DIGIT is a
    :class:`~tactile_force.firmware_bridge.hotplug.HotplugSource`: on unplug its sensor is
    dropped while the other is served, and it comes back on the udev event of its replug.
    Without them (or when udev does not list the DIGIT) it is a plain DigitSource."""
    from tactile_force.firmware_bridge.digit import DigitOptions, DigitSource  # USB code, only now

    options = DigitOptions(sensor=s.serial if s.serial is not None else 0, fps=int(s.fps or 60))
    try:
        watcher = udev_watcher() if s.hotplug else None
        if watcher is not None:
            from tactile_force.firmware_bridge.hotplug import digit_hotplug_source
            from tactile_force.firmware_bridge.usb_ids import DeviceKind

            serial = options.sensor
            seen = [d for d in watcher.present.values() if d.kind is DeviceKind.DIGIT]
            if (isinstance(serial, int) and serial < len(seen)) or any(d.serial == serial for d in seen):
                return digit_hotplug_source(options, watcher, name=s.name)
            logging.getLogger(__name__).warning(
                "sensor '%s': udev lists no DIGIT %s; opening it by the sysfs lookup, without hot-plug", s.name, serial)
        return DigitSource(options)  # udev does not list it: the sysfs lookup (and its message)
    except SourceError as exc:
        raise SourceError(f"sensor '{s.name}' (digit {s.serial}): {exc}") from None


def _open_gelsight_mini(s: SensorSpec, clock: Clock):
    from tactile_force.firmware_bridge import gelsight  # USB sensor code, imported only now

    try:
        return gelsight.GelSightMiniSource(gelsight.GelSightMiniOptions(sensor=s.device, fps=s.fps or 25.0),
                                           name=s.name, clock=clock)
    except SourceError as exc:
        raise SourceError(f"sensor '{s.name}' (gelsight_mini {s.device}): {exc}") from None


def _open_replay(s: SensorSpec, clock: Clock):
    from ..sources import ReplayFolderSource

    assert s.path is not None  # required key of the kind
    return ReplayFolderSource(s.path, fps=s.fps, name=s.name, clock=clock)


def _open_video(s: SensorSpec, clock: Clock):
    from ..sources import VideoFileSource

    assert s.path is not None  # required key of the kind
    return VideoFileSource(s.path, fps=s.fps, name=s.name, clock=clock)


def _open_virtual(s: SensorSpec, clock: Clock):
    try:
        from ..synthetic import VirtualDigitSource
    except ImportError as exc:
        raise SceneError(f"sensor '{s.name}': source 'virtual' needs tactile_force.edge.synthetic.VirtualDigitSource, "
                         f"which this installation lacks ({exc})") from None
    return VirtualDigitSource(seed=s.seed, n_grasps=s.n_grasps, fps=s.fps or 60.0)


def _paced(s: SensorSpec) -> str:
    return f"paced at {s.fps:g} fps" if s.fps else "as fast as read"


#: The one table of source kinds. Keys here are per kind; every sensor also has
#: name, source, background and gate.
SOURCE_KINDS: dict[str, SourceKind] = {
    "camera": SourceKind(
        "camera", CameraKeys, GateOptions, _open_camera,
        lambda s: f"camera {s.device} via OpenCV V4L2 at {s.fps:g} fps, newest frame only"),
    "digit": SourceKind(
        "digit", DigitKeys, GateOptions, _open_digit,
        lambda s: f"DIGIT {s.serial} (found by serial via USB discovery) at {s.fps:g} fps"
                  + (", hot-plug through udev events when pyudev is available" if s.hotplug else "")),
    "gelsight_mini": SourceKind(
        "gelsight_mini", GelSightMiniKeys, GateOptions.gelsight_mini, _open_gelsight_mini,
        lambda s: f"GelSight Mini {s.device} via OpenCV V4L2, cropped 1/7 per side, 320x240 portrait, "
                  "newest frame only"),
    "replay": SourceKind(
        "replay", ReplayKeys, GateOptions, _open_replay, lambda s: f"replay {s.path} ({_paced(s)})", live=False),
    "video": SourceKind(
        "video", VideoKeys, GateOptions, _open_video, lambda s: f"video {s.path} ({_paced(s)})", live=False),
    "virtual": SourceKind(
        "virtual", VirtualKeys, GateOptions, _open_virtual,
        lambda s: f"virtual DIGIT (seed {s.seed}, {s.n_grasps} grasps, {s.fps:g} fps)", live=False),
}
SOURCES = tuple(SOURCE_KINDS)


# -- building -----------------------------------------------------------------------------
def kind_of(s: SensorSpec) -> SourceKind:
    """The source kind of a sensor table (its keys, gate preset, opener and description)."""
    return SOURCE_KINDS[s.source]


def open_source(s: SensorSpec, clock: Clock | None = None):
    """Open the FrameSource a sensor spec names (device libraries only for that device)."""
    import time

    return kind_of(s).opener(s, clock or time.monotonic_ns)
