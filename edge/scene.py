"""Scene files (TOML): what the setup is, validated once, and building only the stages it needs.

    [runtime]
    bundle = "default"        # a bundle path, "default" (the embedded model), or a list = ladder
    backend = "cpu"           # "cpu" | "oak"
    fallback = "cpu"          # optional: use the CPU when the OAK cannot be used
    deadline_ms = 16.7
    threads = 1
    max_frames = 0            # 0 = until the sources end

    [gate]                    # GateOptions fields: override the source kind's preset, key by key
    threshold = 14.0

    [depth]                   # DepthOptions fields (depth bundles only)
    mode = "paper"            # paper mode: the zero-depth reference is the gate's background
    mapping = "package:virtual_digit_depth.npz"   # package:FILE = a file shipped in edge/assets

    [[sensor]]
    name = "left"
    source = "replay"         # a kind of SOURCE_KINDS: camera, digit, gelsight_mini, replay, video, virtual
    path = "grasp_01"         # replay folder / video file
    fps = 60.0                # pace at this rate (omit = as fast as read)
    background = "bg.png"     # optional no-contact image(s); else learnt from the first frames
    gate = { threshold = 14.0 }   # per-sensor overrides

    [[output]]
    kind = "csv"              # "stdout" | "csv" | "jsonl" | "mcap" | "ros2"
    path = "readings.csv"
    # mcap only: frames = true logs each gated frame (JPEG), mask = true its contact mask (PNG)

A ``digit`` sensor follows unplug / replug through udev events (pyudev) unless
``hotplug = false``; without pyudev / libudev it is opened without (logged once).

Input paths (bundles, replay folders, videos, backgrounds, depth mappings) are relative to
the scene file; output paths are relative to the working directory (never the package
folder). ``~`` and ``$VARS`` are expanded. Every key is checked for type, range and (paths)
readability / writability by :func:`load_scene` before anything heavy is loaded; errors
name the file and the key. No device library (depthai, pyusb, hidapi) and no depth code is
imported unless the scene needs it.

Each source kind is one entry of :data:`SOURCE_KINDS`: its keys (types, defaults, checks),
its gate preset and its opener. Adding a kind means adding one entry.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser from PyPI (a core dependency there)
    import tomli as tomllib

from .errors import AcceleratorUnavailableError, BundleError, SceneError, SourceError
from .gate import ContactGate, GateOptions
from .runtime import resolve_package_path

BACKENDS = ("cpu", "oak")
OUTPUT_KINDS = ("stdout", "csv", "jsonl", "mcap", "ros2")
#: Output kinds that write a file (need ``path``).
FILE_OUTPUTS = ("csv", "jsonl", "mcap")
DEPTH_MODES = ("exact", "paper")
PACKAGE_DIR = Path(__file__).resolve().parent

Clock = Callable[[], int]


def default_bundle_path() -> Path:
    """Where the embedded default bundle lives: <package>/models/default."""
    return PACKAGE_DIR / "models" / "default"


def shipped_bundles() -> dict[str, Path]:
    """The bundles shipped in the package, by folder name, the default first.

    Returns
    -------
    dict[str, pathlib.Path]
        ``{"default": .../models/default, "d": .../models/d, "rgbmod_d": .../models/rgbmod_d}``
        in this install: every folder of ``<package>/models`` holding a ``model.json`` (the
        compact RGBmod default, and compact D and RGBmod+D bundles trained on the virtual
        DIGIT's synthetic frames only). Empty when none is installed.
    """
    root = default_bundle_path().parent
    found = sorted(p for p in root.iterdir() if p.is_dir() and (p / "model.json").is_file()) if root.is_dir() else []
    found.sort(key=lambda p: p.name != "default")  # stable: the default first, the rest by name
    return {p.name: p for p in found}


# -- typed records ------------------------------------------------------------------------
@dataclass
class SensorSpec:
    """One [[sensor]] table after validation. Which fields a kind uses, and their
    defaults, come from its :class:`SourceKind` entry; paths are absolute."""

    name: str
    source: str
    path: Path | None = None
    device: int | str = 0
    serial: str | int | None = None
    fps: float | None = None
    background: Path | None = None
    gate: GateOptions = field(default_factory=GateOptions)
    seed: int = 0
    n_grasps: int = 3
    hotplug: bool = True

    @property
    def kind(self) -> SourceKind:
        return SOURCE_KINDS[self.source]


@dataclass
class OutputSpec:
    """One [[output]] table. path: absolute (file outputs); topic: ROS 2 topic (ros2);
    frames / mask: also log each gated frame (JPEG) / its contact mask (PNG) (mcap only)."""

    kind: str
    path: Path | None = None
    live: bool = False
    fsync: bool = False
    topic: str | None = None
    frames: bool = False
    mask: bool = False


@dataclass
class Scene:
    """A parsed scene. bundles: one path, or several (a ladder, most accurate picked).
    path: the scene file, None for a scene built from command-line flags."""

    path: Path | None
    sensors: list[SensorSpec]
    bundles: list[Path]
    backend: str = "cpu"
    fallback: str | None = None
    deadline_ms: float = 16.7
    threads: int = 1
    max_frames: int = 0
    report_stale: bool = True
    oak_archive: Path | None = None
    oak_device: str | None = None
    depth: dict[str, Any] = field(default_factory=dict)
    outputs: list[OutputSpec] = field(default_factory=list)

    @property
    def origin(self) -> str:
        """Where the scene came from, for messages: the file, or 'command line'."""
        return str(self.path) if self.path is not None else "command line"


# -- key checks ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Key:
    """One scene key: accepted TOML types, default, what is expected (for messages), an
    extra check on the value, whether it must be given, and whether it is an input path
    (relative to the scene file)."""

    types: tuple[type, ...]
    default: Any
    expected: str
    check: Callable[[Any], bool] | None = None
    required: bool = False
    path: bool = False


def _finite_pos(v: Any) -> bool:
    return math.isfinite(v) and v > 0


def _fps(default: float | None) -> Key:
    return Key((int, float), default, "a finite frame rate > 0 (frames per second)", _finite_pos)


_DEVICE = Key((int, str), 0, "a camera index or a /dev/videoN path", lambda v: not isinstance(v, int) or v >= 0)


def _err(where: str, msg: str) -> SceneError:
    return SceneError(f"{where}: {msg}")


def _table(value: Any, where: str, what: str) -> dict:
    if not isinstance(value, dict):
        raise _err(where, f"expected a table ({what}), got {value!r}")
    return value


def _check_keys(table: dict, allowed: set[str] | dict, where: str) -> None:
    for k in table:
        if k not in allowed:
            raise _err(where, f"unknown key '{k}'; expected one of {sorted(allowed)}")


def _value(table: dict, name: str, key: Key, where: str) -> Any:
    """The validated value of ``name`` in ``table`` (or the key's default)."""
    if name not in table:
        if key.required:
            raise _err(where, f"'{name}' is required; expected {key.expected}")
        return key.default
    v = table[name]
    if isinstance(v, bool) and bool not in key.types:
        raise _err(where, f"'{name}' = {v!r}; expected {key.expected}")
    if not isinstance(v, key.types):
        raise _err(where, f"'{name}' = {v!r}; expected {key.expected}")
    if isinstance(v, float) and not math.isfinite(v) and key.check is not None:
        raise _err(where, f"'{name}' = {v!r}; expected {key.expected}")
    if key.check is not None and not key.check(v):
        raise _err(where, f"'{name}' = {v!r}; expected {key.expected}")
    if isinstance(v, str) and not v and key.path:
        raise _err(where, f"'{name}' is empty; expected {key.expected}")
    return v


def _expand(value: str) -> Path:
    return Path(os.path.expandvars(os.path.expanduser(value)))


def _in_path(base: Path, value: str) -> Path:
    """An input path: relative to the scene file's folder (``base``)."""
    p = _expand(value)
    return p if p.is_absolute() else (base / p)


def _out_path(value: str) -> Path:
    """An output path: relative to the working directory, never the scene or package folder."""
    return _expand(value).absolute()


# -- source kinds ---------------------------------------------------------------------------
@dataclass(frozen=True)
class SourceKind:
    """One kind of frame source: its own keys (beyond name, source, background, gate), its
    gate preset, how to open it and one line saying what it is."""

    name: str
    keys: dict[str, Key]
    gate_preset: Callable[[], GateOptions]
    opener: Callable[[SensorSpec, Clock], Any]
    describe: Callable[[SensorSpec], str]
    live: bool = True


def _open_camera(s: SensorSpec, clock: Clock):
    from .sources import CameraSource

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
    from .sources import ReplayFolderSource

    assert s.path is not None  # required key of the kind
    return ReplayFolderSource(s.path, fps=s.fps, name=s.name, clock=clock)


def _open_video(s: SensorSpec, clock: Clock):
    from .sources import VideoFileSource

    assert s.path is not None  # required key of the kind
    return VideoFileSource(s.path, fps=s.fps, name=s.name, clock=clock)


def _open_virtual(s: SensorSpec, clock: Clock):
    try:
        from .synthetic import VirtualDigitSource
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
        "camera", {"device": _DEVICE, "fps": _fps(60.0)}, GateOptions, _open_camera,
        lambda s: f"camera {s.device} via OpenCV V4L2 at {s.fps:g} fps, newest frame only"),
    "digit": SourceKind(
        "digit",
        {"serial": Key((str, int), None, "a DIGIT serial such as 'D20001', or an index among attached DIGITs",
                       lambda v: not isinstance(v, int) or v >= 0, required=True),
         "fps": Key((int,), 60, "60 or 30 (QVGA frame rates of a DIGIT)", lambda v: v in (30, 60)),
         "hotplug": Key((bool,), True, "true or false (follow unplug / replug through udev events)")},
        GateOptions, _open_digit,
        lambda s: f"DIGIT {s.serial} (found by serial via USB discovery) at {s.fps:g} fps"
                  + (", hot-plug through udev events when pyudev is available" if s.hotplug else "")),
    "gelsight_mini": SourceKind(
        "gelsight_mini",
        {"device": Key((int, str), 0, "a GelSight Mini serial, an index or a /dev/videoN path",
                       lambda v: not isinstance(v, int) or v >= 0),
         "fps": _fps(25.0)},
        GateOptions.gelsight_mini, _open_gelsight_mini,
        lambda s: f"GelSight Mini {s.device} via OpenCV V4L2, cropped 1/7 per side, 320x240 portrait, "
                  "newest frame only"),
    "replay": SourceKind(
        "replay", {"path": Key((str,), None, "a replay folder (images/N.png [+ forces/force_N.txt])",
                               required=True, path=True), "fps": _fps(None)},
        GateOptions, _open_replay, lambda s: f"replay {s.path} ({_paced(s)})", live=False),
    "video": SourceKind(
        "video", {"path": Key((str,), None, "a video file", required=True, path=True), "fps": _fps(None)},
        GateOptions, _open_video, lambda s: f"video {s.path} ({_paced(s)})", live=False),
    "virtual": SourceKind(
        "virtual",
        {"seed": Key((int,), 0, "an integer"),
         "n_grasps": Key((int,), 3, "an integer >= 1 (grasps the virtual DIGIT plays)", lambda v: v >= 1),
         "fps": _fps(60.0)},
        GateOptions, _open_virtual,
        lambda s: f"virtual DIGIT (seed {s.seed}, {s.n_grasps} grasps, {s.fps:g} fps)", live=False),
}
SOURCES = tuple(SOURCE_KINDS)
_COMMON_SENSOR_KEYS = {"name", "source", "background", "gate"}

_RUNTIME_KEYS: dict[str, Key] = {
    "backend": Key((str,), "cpu", f"one of {BACKENDS}", lambda v: v in BACKENDS),
    "fallback": Key((str,), None, '"cpu" (or leave it out)', lambda v: v == "cpu"),
    "deadline_ms": Key((int, float), 16.7, "a finite number of milliseconds > 0", _finite_pos),
    "threads": Key((int,), 1, "an integer >= 1", lambda v: v >= 1),
    "max_frames": Key((int,), 0, "an integer >= 0 (0 = until the sources end)", lambda v: v >= 0),
    "report_stale": Key((bool,), True, "true or false"),
    "oak_archive": Key((str,), None, "the NN Archive (.tar.xz) of the bundle for the OAK", path=True),
    "oak_device": Key((str,), None, "an OAK device id"),
}
_DEPTH_KEYS: dict[str, Key] = {
    "mapping": Key((str,), None, "the colour->normal .npz (a path, or package:FILE for a file in edge/assets)",
                   path=True),
    "mode": Key((str,), "exact", f"one of {DEPTH_MODES}", lambda v: v in DEPTH_MODES),
    "levels_per_px": Key((int, float), None, "a finite number > 0", _finite_pos),
    "paper_scale": Key((int, float), None, "a finite number > 0", _finite_pos),
    "gel_width_m": Key((int, float), None, "a finite gel width in metres > 0", _finite_pos),
    "gel_height_m": Key((int, float), None, "a finite gel height in metres > 0", _finite_pos),
    "saturated_fraction": Key((int, float), None, "a number in [0, 1]", lambda v: 0 <= v <= 1),
    "solver_dtype": Key((str,), None, '"float32" or "float64"', lambda v: v in ("float32", "float64")),
}
_OUTPUT_KEYS = {"kind", "path", "live", "fsync", "topic", "frames", "mask"}


def _gate_options(table: dict, base: GateOptions, where: str) -> GateOptions:
    """``base`` with the keys of ``table`` replaced; each checked against the type of the
    GateOptions field (int, finite float, bool) and then by GateOptions.validate."""
    defaults = {f.name: f.default for f in dataclasses.fields(GateOptions)}
    _check_keys(table, set(defaults), where)
    for k, v in table.items():
        want = type(defaults[k])
        if want is bool:
            ok, expected = isinstance(v, bool), "true or false"
        elif want is int:
            ok, expected = isinstance(v, int) and not isinstance(v, bool), "an integer"
        else:
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            expected = "a finite number"
        if not ok:
            raise _err(where, f"'{k}' = {v!r}; expected {expected}")
    opts = dataclasses.replace(base, **table)
    try:
        opts.validate()
    except ValueError as exc:
        raise _err(where, str(exc)) from None
    return opts


def _bundles(rt: dict, base: Path, where: str) -> list[Path]:
    bundle = rt.get("bundle", "default")
    items = bundle if isinstance(bundle, list) else [bundle]
    if not items or not all(isinstance(b, str) and b for b in items):
        raise _err(where, f"'bundle' = {bundle!r}; expected a path, \"default\", or a list of paths (ladder)")
    return [default_bundle_path() if b == "default" else _in_path(base, b) for b in items]


def _depth(data: dict, base: Path, where: str) -> dict[str, Any]:
    table = _table(data.get("depth", {}), f"{where} [depth]", "DepthOptions fields")
    _check_keys(table, _DEPTH_KEYS, f"{where} [depth]")
    out: dict[str, Any] = {}
    for k, key in _DEPTH_KEYS.items():
        v = _value(table, k, key, f"{where} [depth]")
        if k in table:
            out[k] = float(v) if isinstance(v, int) and float in key.types else v
    if "mapping" in out:
        m = str(out["mapping"])
        out["mapping"] = resolve_package_path(m) if m.startswith("package:") else str(_in_path(base, m))
    return out


def _sensor(t: Any, i: int, gate_table: dict, base: Path, where: str) -> SensorSpec:
    ws = f"{where} [[sensor]] #{i + 1}"
    t = _table(t, ws, "name, source and the keys of its kind")
    src = t.get("source")
    if not isinstance(src, str) or src not in SOURCE_KINDS:
        raise _err(ws, f"'source' = {src!r}; expected one of {SOURCES}")
    kind = SOURCE_KINDS[src]
    _check_keys(t, _COMMON_SENSOR_KEYS | set(kind.keys), ws)
    name = _value(t, "name", Key((str,), f"sensor{i}", "a non-empty name", lambda v: bool(v)), ws)
    values: dict[str, Any] = {}
    for k, key in kind.keys.items():
        if key.required and k not in t:
            raise _err(ws, f"source '{src}' needs '{k}' ({key.expected})")
        v = _value(t, k, key, ws)
        if v is not None and key.path:
            v = _in_path(base, v)
        elif k == "fps" and v is not None:
            v = float(v)
        values[k] = v
    bg = _value(t, "background", Key((str,), None, "a no-contact image file or folder", path=True), ws)
    per_sensor = _value(t, "gate", Key((dict,), {}, "a table of GateOptions fields"), ws)
    preset = _gate_options(gate_table, kind.gate_preset(), f"{where} [gate]")
    gate = _gate_options(per_sensor, preset, f"{ws} gate")
    return SensorSpec(name=name, source=src, background=_in_path(base, bg) if bg else None, gate=gate, **values)


def _output(t: Any, i: int, where: str) -> OutputSpec:
    wo = f"{where} [[output]] #{i + 1}"
    t = _table(t, wo, "kind and its keys")
    _check_keys(t, _OUTPUT_KEYS, wo)
    kind = _value(t, "kind", Key((str,), None, f"one of {OUTPUT_KINDS}", lambda v: v in OUTPUT_KINDS,
                                 required=True), wo)
    opath = _value(t, "path", Key((str,), None, "a file path (relative to the working directory)",
                                  lambda v: bool(v)), wo)
    if kind in FILE_OUTPUTS and opath is None:
        raise _err(wo, f"output '{kind}' needs 'path' (a file, relative to the working directory)")
    if kind not in FILE_OUTPUTS and opath is not None:
        raise _err(wo, f"output '{kind}' writes no file; remove 'path'")
    topic = _value(t, "topic", Key((str,), None, "a ROS 2 topic name such as '/tactile/force'",
                                   lambda v: bool(v) and " " not in v), wo)
    if kind == "ros2" and topic is None:
        raise _err(wo, "output 'ros2' needs 'topic' (e.g. '/tactile/force')")
    if topic is not None:
        from .outputs.ros2_names import ros_topic  # no DDS dependency

        try:
            topic = ros_topic(topic, "topic")
        except SceneError as exc:
            raise _err(wo, str(exc)) from None
    images = {k: _value(t, k, Key((bool,), False, f"true or false (log each frame's {what})"), wo)
              for k, what in (("frames", "image"), ("mask", "contact mask"))}
    for k, v in images.items():
        if v and kind != "mcap":
            raise _err(wo, f"'{k}' is for kind = \"mcap\" only; output '{kind}' writes readings")
    return OutputSpec(kind, _out_path(opath) if opath else None,
                      _value(t, "live", Key((bool,), False, "true or false"), wo),
                      _value(t, "fsync", Key((bool,), False, "true or false"), wo), topic, **images)


def parse_scene(data: dict, path: Path | None, base: Path | None = None) -> Scene:
    """Validate a TOML dict (types, ranges, finite numbers); SceneError names the key.

    path: the scene file (None for a command-line scene); base: the folder input paths are
    relative to (default: the scene file's folder, else the working directory).
    """
    where = str(path) if path is not None else "command line"
    base = base or (path.parent if path is not None else Path.cwd())
    _table(data, where, "a scene")
    _check_keys(data, {"runtime", "gate", "depth", "sensor", "output"}, where)
    w = f"{where} [runtime]"
    rt = _table(data.get("runtime", {}), w, "runtime settings")
    _check_keys(rt, set(_RUNTIME_KEYS) | {"bundle"}, w)
    r = {k: _value(rt, k, key, w) for k, key in _RUNTIME_KEYS.items()}
    if r["backend"] == "oak" and r["oak_archive"] is None and r["fallback"] != "cpu":
        raise _err(w, "backend 'oak' needs 'oak_archive' (the bundle's NN Archive .tar.xz), or fallback = \"cpu\"")
    gate_table = _table(data.get("gate", {}), f"{where} [gate]", "GateOptions fields")
    _gate_options(gate_table, GateOptions(), f"{where} [gate]")  # keys and types, once

    raw_sensors = data.get("sensor", [])
    if not isinstance(raw_sensors, list):
        raise _err(where, f"'sensor' = {raw_sensors!r}; expected [[sensor]] tables (one or two)")
    if not raw_sensors:
        raise _err(where, "no [[sensor]] tables; expected one or two sensors")
    if len(raw_sensors) > 2:
        raise _err(where, f"{len(raw_sensors)} [[sensor]] tables; expected one or two (one per finger)")
    sensors = [_sensor(t, i, gate_table, base, where) for i, t in enumerate(raw_sensors)]
    if len({s.name for s in sensors}) != len(sensors):
        raise _err(where, f"sensor names {[s.name for s in sensors]} must be unique")
    raw_outputs = data.get("output", [])
    if not isinstance(raw_outputs, list):
        raise _err(where, f"'output' = {raw_outputs!r}; expected [[output]] tables")
    outputs = [_output(t, i, where) for i, t in enumerate(raw_outputs)]
    return Scene(path=path, sensors=sensors, bundles=_bundles(rt, base, w), backend=r["backend"],
                 fallback=r["fallback"], deadline_ms=float(r["deadline_ms"]), threads=r["threads"],
                 max_frames=r["max_frames"], report_stale=r["report_stale"],
                 oak_archive=_in_path(base, r["oak_archive"]) if r["oak_archive"] else None,
                 oak_device=r["oak_device"], depth=_depth(data, base, where), outputs=outputs)


# -- paths -----------------------------------------------------------------------------------
def _readable(p: Path, want: str) -> str | None:
    """Why ``p`` cannot be read as ``want`` ('file', 'folder' or 'file or folder'), else None."""
    if not p.exists():
        unset = [w for w in str(p).split("/") if w.startswith("$")]
        return f"{p} not found" + (f" (environment variable {unset[0]} is not set)" if unset else "")
    if want == "file" and not p.is_file():
        return f"{p} is not a file"
    if want == "folder" and not p.is_dir():
        return f"{p} is not a folder"
    if not os.access(p, os.R_OK):
        return f"{p} is not readable (permissions)"
    return None


def output_problem(p: Path) -> str | None:
    """Why a reading file cannot be written at ``p``, else None. Probes the folder for real
    (a file is created and removed), so it holds for root and read-only file systems too.
    Missing parent folders are fine when their nearest existing ancestor is writable; the
    package folder is refused."""
    if p.is_dir():
        return f"{p} is a folder; expected a file path"
    try:
        p.resolve().relative_to(PACKAGE_DIR)
        return f"{p} is inside the installed package ({PACKAGE_DIR}); write readings elsewhere"
    except ValueError:
        pass
    anc = p.parent
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        return f"{p}: {anc} is not a folder"
    if p.exists():
        try:
            with open(p, "a"):
                pass
        except OSError as exc:
            return f"{p} is not writable ({exc.strerror})"
        return None
    try:
        with tempfile.NamedTemporaryFile(dir=anc, prefix=".tactile_force_probe_"):
            pass
    except OSError as exc:
        return f"{p}: cannot create files in {anc} ({exc.strerror})"
    return None


def scene_problems(scene: Scene) -> list[str]:
    """Every missing input and unwritable output of a parsed scene, each naming the key and
    the file ('' when all is well). Cheap: reads no bundle, opens no device."""
    where = scene.origin
    out: list[str] = []
    for b in scene.bundles:
        if (p := _readable(b, "folder")) or (p := _readable(b / "model.json", "file")):
            out.append(f"{where} [runtime] bundle: {p} (expected a bundle folder with model.json)")
    if (scene.backend == "oak" and scene.oak_archive is not None and scene.fallback != "cpu"
            and (p := _readable(scene.oak_archive, "file"))):
            out.append(f"{where} [runtime] oak_archive: {p} (or set fallback = \"cpu\" to run on the CPU without it)")
    if "mapping" in scene.depth and (p := _readable(Path(scene.depth["mapping"]), "file")):
        out.append(f"{where} [depth] mapping: {p}")
    for i, s in enumerate(scene.sensors):
        ws = f"{where} [[sensor]] #{i + 1} ({s.name})"
        if s.path is not None:
            want = "folder" if s.source == "replay" else "file"
            if p := _readable(s.path, want):
                out.append(f"{ws} path: {p}")
        if s.background is not None and (p := _readable(s.background, "file or folder")):
            out.append(f"{ws} background: {p}")
    paths = [o.path for o in scene.outputs if o.path is not None]
    for i, o in enumerate(scene.outputs):
        if o.path is None:
            continue
        if paths.count(o.path) > 1:
            out.append(f"{where} [[output]] #{i + 1} path: {o.path} is used by more than one output")
        elif p := output_problem(o.path):
            out.append(f"{where} [[output]] #{i + 1} path: {p}")
    return out


def check_scene(scene: Scene) -> Scene:
    """Raise SceneError listing every problem :func:`scene_problems` finds."""
    problems = scene_problems(scene)
    if problems:
        raise SceneError("; ".join(problems))
    return scene


def load_scene(path: str | os.PathLike, check: bool = True) -> Scene:
    """Read and validate a scene file; ``check`` also checks its paths (:func:`check_scene`)."""
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"{p}: scene file not found")
    try:
        data = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(f"{p}: not valid TOML ({exc})") from None
    except OSError as exc:
        raise SceneError(f"{p}: cannot read ({exc.strerror})") from None
    scene = parse_scene(data, p.resolve())
    return check_scene(scene) if check else scene


# -- scenes from flags, and back to TOML -----------------------------------------------------
def source_table(source: str) -> dict[str, Any]:
    """The [[sensor]] keys for a ``--source`` value: a folder (replay), a video file,
    ``digit:SERIAL``, ``gelsight_mini[:SERIAL]``, ``camera:DEVICE`` or ``virtual``."""
    kind, _, arg = source.partition(":")
    if kind == "digit":
        if not arg:
            raise SceneError("--source digit:SERIAL: give the DIGIT's serial, e.g. digit:D20001")
        return {"source": "digit", "serial": int(arg) if arg.isdigit() else arg}
    if kind == "gelsight_mini":
        return {"source": "gelsight_mini", **({"device": int(arg) if arg.isdigit() else arg} if arg else {})}
    if kind == "camera":
        return {"source": "camera", **({"device": int(arg) if arg.isdigit() else arg} if arg else {})}
    if source == "virtual":
        return {"source": "virtual"}
    p = _expand(source)
    if p.is_dir():
        return {"source": "replay", "path": str(p.absolute())}
    if p.is_file():
        return {"source": "video", "path": str(p.absolute())}
    raise SceneError(f"--source {source!r}: no such folder or file; expected a replay folder, a video file, "
                     "digit:SERIAL, gelsight_mini[:SERIAL], camera:DEVICE or virtual")


def output_table(out: str) -> dict[str, Any]:
    """The [[output]] keys for ``--out FILE``: the kind from the suffix (.csv, .jsonl, .mcap)."""
    suffix = Path(out).suffix.lower()
    kinds = {".csv": "csv", ".jsonl": "jsonl", ".mcap": "mcap"}
    if suffix not in kinds:
        raise SceneError(f"--out {out!r}: unknown file type {suffix or '(none)'}; expected .csv, .jsonl or .mcap")
    return {"kind": kinds[suffix], "path": str(_out_path(out))}


def scene_from_flags(source: str, bundle: str = "default", background: str | None = None,
                     outputs: list[str] | None = None, ros2: str | None = None, name: str = "sensor",
                     fps: float | None = None, live_status: bool = False, mcap_frames: bool = False) -> Scene:
    """The Scene a TOML file with these settings would give (validated the same way).
    mcap_frames: the .mcap outputs also log each frame and its contact mask."""
    sensor = {"name": name, **source_table(source)}
    if background is not None:
        sensor["background"] = str(_expand(background).absolute())
    if fps is not None:
        sensor["fps"] = int(fps) if sensor["source"] == "digit" and float(fps).is_integer() else fps
    outs = [output_table(o) for o in outputs or []]
    if mcap_frames:
        if not any(o["kind"] == "mcap" for o in outs):
            raise SceneError("--mcap-frames: no --out FILE.mcap to log the frames to")
        for o in outs:
            if o["kind"] == "mcap":
                o.update(frames=True, mask=True)
    if ros2 is not None:
        outs.append({"kind": "ros2", "topic": ros2})
    outs.insert(0, {"kind": "stdout", "live": live_status})
    data = {"runtime": {"bundle": bundle if bundle == "default" else str(_expand(bundle).absolute())},
            "sensor": [sensor], "output": outs}
    return parse_scene(data, None, Path.cwd())


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, (str, Path)):
        return json.dumps(str(v))
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_toml_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r} to TOML")


def scene_to_toml(scene: Scene) -> str:
    """The scene as a TOML file that :func:`load_scene` reads back to an equal Scene
    (absolute paths; gate keys only where they differ from the source kind's preset)."""
    lines = ["# written by tactile-force run --save-scene", "", "[runtime]"]
    bundles = ["default" if b == default_bundle_path() else str(b) for b in scene.bundles]
    rt: dict[str, Any] = {"bundle": bundles[0] if len(bundles) == 1 else bundles, "backend": scene.backend,
                          "deadline_ms": scene.deadline_ms, "threads": scene.threads,
                          "max_frames": scene.max_frames, "report_stale": scene.report_stale}
    for k, v in (("fallback", scene.fallback), ("oak_archive", scene.oak_archive), ("oak_device", scene.oak_device)):
        if v is not None:
            rt[k] = v
    lines += [f"{k} = {_toml_value(v)}" for k, v in rt.items()]
    if scene.depth:
        lines += ["", "[depth]"] + [f"{k} = {_toml_value(v)}" for k, v in scene.depth.items()]
    for s in scene.sensors:
        kind = s.kind
        lines += ["", "[[sensor]]", f"name = {_toml_value(s.name)}", f"source = {_toml_value(s.source)}"]
        for k in kind.keys:
            v = getattr(s, k)
            if v is not None:
                lines.append(f"{k} = {_toml_value(int(v) if k == 'fps' and s.source == 'digit' else v)}")
        if s.background is not None:
            lines.append(f"background = {_toml_value(s.background)}")
        preset = kind.gate_preset()
        diff = {f.name: getattr(s.gate, f.name) for f in dataclasses.fields(GateOptions)
                if getattr(s.gate, f.name) != getattr(preset, f.name)}
        if diff:
            lines.append(f"gate = {_toml_value(diff)}")
    for o in scene.outputs:
        lines += ["", "[[output]]", f"kind = {_toml_value(o.kind)}"]
        for k in ("path", "topic"):
            if getattr(o, k) is not None:
                lines.append(f"{k} = {_toml_value(getattr(o, k))}")
        for k in ("live", "fsync", "frames", "mask"):
            if getattr(o, k):
                lines.append(f"{k} = true")
    return "\n".join(lines) + "\n"


def save_scene(scene: Scene, path: str | os.PathLike) -> Path:
    """Write :func:`scene_to_toml` to ``path`` (relative to the working directory)."""
    p = _out_path(str(path))
    if problem := output_problem(p):
        raise SceneError(f"--save-scene: {problem}")
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(scene_to_toml(scene))
    return p


# -- planning ---------------------------------------------------------------------------
def _bundle_summary(path: Path) -> tuple[bool | None, str]:
    """(needs_depth or None if unreadable, one-line description)."""
    from .bundle import load_bundle

    try:
        b = load_bundle(path)
    except BundleError as exc:
        return None, f"{path}: NOT USABLE ({exc})"
    m = b.manifest
    return m.needs_depth, f"{b.name}: variant {m.variant}, {m.precision}, sha256 ok ({path})"


def bundle_problems(scene: Scene) -> list[str]:
    """Bundles that cannot be loaded (hash, manifest), one message each. Reads the bundles."""
    out = []
    for b in scene.bundles:
        nd, text = _bundle_summary(b)
        if nd is None:
            out.append(f"{scene.origin} [runtime] bundle: {text}")
    return out


def _output_line(o: OutputSpec) -> str:
    target = f" {o.path}" if o.path else (f" topic {o.topic}" if o.topic else "")
    images = " + ".join(w for w, on in (("frames", o.frames), ("contact masks", o.mask)) if on)
    return (f"  output       {o.kind}{target}{' (live status line)' if o.live else ''}"
            + (f" (with {images})" if images else ""))


def describe_scene(scene: Scene) -> list[str]:
    """Human lines: the stages that will run, in order. Loads no model, opens no device."""
    lines = [f"scene {scene.origin}"]
    needs = []
    for b in scene.bundles:
        nd, text = _bundle_summary(b)
        needs.append(nd)
        lines.append(f"  bundle       {text}")
    needs_depth = any(n for n in needs if n is not None)
    if len(scene.bundles) > 1:
        lines.append(f"  ladder       measure p99 of {len(scene.bundles)} bundles at start; keep the most accurate "
                     f"within {scene.deadline_ms:g} ms")
    for s in scene.sensors:
        missing = "  [MISSING]" if s.path is not None and not s.path.exists() else ""
        lines.append(f"  source:{s.name:<6} {s.kind.describe(s)}{missing}")
        bg = (f"background from {s.background}" if s.background
              else f"background = mean of first {s.gate.background_frames} frames (learnt: keep the sensor untouched)")
        lines.append(f"  gate:{s.name:<8} threshold {s.gate.threshold:g}, on/off area {s.gate.on_area_frac:g}/"
                     f"{s.gate.off_area_frac:g}, downscale x{s.gate.downscale}, {bg}")
        if needs_depth:
            mapping = scene.depth.get("mapping", "from the bundle manifest, else MISSING: set [depth] mapping")
            mode = scene.depth.get("mode", "exact")
            ref = ", zero-depth reference = the gate's background" if mode == "paper" else ""
            lines.append(f"  depth:{s.name:<7} DepthStage {mode} (RGB -> normals -> gradients -> Poisson -> masked "
                         f"depth; mapping {mapping}{ref})")
    be = scene.backend + (f" {scene.oak_archive}" if scene.backend == "oak" else "")
    be += f" (fallback {scene.fallback})" if scene.fallback else ""
    lines.append(f"  inference    {be}, {scene.threads} thread(s), batch {len(scene.sensors)} when all in contact, "
                 f"deadline {scene.deadline_ms:g} ms")
    if not needs_depth:
        lines.append("  (no depth stage: RGB-only bundle)")
    lines += [_output_line(o) for o in scene.outputs or [OutputSpec("stdout")]]
    return lines


# -- building -----------------------------------------------------------------------------
def open_source(s: SensorSpec, clock: Clock | None = None):
    """Open the FrameSource a sensor spec names (device libraries only for that device)."""
    import time

    return s.kind.opener(s, clock or time.monotonic_ns)


def load_model(scene: Scene) -> tuple[Any, str, list[str]]:
    """(model, backend actually used, notes) for the scene's bundle(s) and backend."""
    from .inference import OnnxForceModel, choose_bundle

    notes: list[str] = []
    if scene.backend == "oak":
        try:
            if scene.oak_archive is None:
                raise AcceleratorUnavailableError("no 'oak_archive' given in [runtime]")
            from tactile_force.firmware_bridge import oak  # depthai is imported there, only now

            opts = oak.OakOptions(archive=scene.oak_archive, device_id=scene.oak_device)
            return oak.OakForceModel(scene.bundles[0], opts), "oak", notes
        except (AcceleratorUnavailableError, ImportError, SourceError) as exc:
            if scene.fallback != "cpu":
                raise SceneError(f"{scene.origin}: backend 'oak' unavailable ({exc}); "
                                 "set fallback = \"cpu\" in [runtime] to run on the CPU instead") from None
            notes.append(f"OAK unavailable ({exc}); falling back to the CPU")
    if len(scene.bundles) > 1:
        ladder: list[str | os.PathLike] = list(scene.bundles)
        model, choice = choose_bundle(ladder, scene.deadline_ms, threads=scene.threads)
        notes.append(choice.reason)
        return model, "cpu", notes
    return OnnxForceModel(scene.bundles[0], threads=scene.threads), "cpu", notes


def open_outputs(scene: Scene, p99_ms=None) -> list:
    """One writer per [[output]]; MCAP and ROS 2 writers are imported only when used."""
    from .outputs import CsvWriter, JsonlWriter, StdoutWriter

    sinks: list = []
    try:
        for o in scene.outputs:
            path = o.path if o.path is not None else Path(os.devnull)  # file outputs always have one
            if o.kind == "csv":
                sinks.append(CsvWriter(path, fsync=o.fsync))
            elif o.kind == "jsonl":
                sinks.append(JsonlWriter(path, fsync=o.fsync))
            elif o.kind == "mcap":
                from .outputs.mcap_log import McapWriter  # the 'mcap' extra, imported only now

                sinks.append(McapWriter(path, frames=o.frames, mask=o.mask, fsync=o.fsync))
            elif o.kind == "ros2":
                from .outputs.ros2_topic import Ros2Publisher  # the 'ros2' extra, imported only now

                assert o.topic is not None  # parse_scene requires it
                sinks.append(Ros2Publisher(o.topic))
            else:
                sinks.append(StdoutWriter(live=o.live, p99_ms=p99_ms, every=4))
    except BaseException:
        for s in sinks:
            s.close()
        raise
    return sinks


class LearningWatch:
    """Wraps a source whose gate learns its background from the first ``n`` frames: once
    they are read, checks them with a gate of the same options (background = the first of
    them) and calls ``warn`` when some already differ like contact (something touched or
    moved while the background was learnt). Everything else is the wrapped source's."""

    def __init__(self, source, sensor: str, options: GateOptions, warn: Callable[[str], None]) -> None:
        self.source = source
        self.sensor = sensor
        self.options = options
        self.warn = warn
        self._seen: list = []
        self.checked = False

    @property
    def stats(self):
        return self.source.stats

    @property
    def name(self) -> str:
        return self.source.name

    def __getattr__(self, attr: str):
        if attr == "source":  # not set yet (copy, pickle): no recursion
            raise AttributeError(attr)
        return getattr(self.source, attr)  # reopen(), device, node ... of the wrapped source

    def read(self):
        tf = self.source.read()
        if tf is not None and not self.checked:
            self._seen.append(tf.frame.copy())
            if len(self._seen) >= self.options.background_frames:
                self._check()
        return tf

    def _check(self) -> None:
        from .errors import FrameError

        self.checked = True
        frames, self._seen = self._seen, []
        gate = ContactGate(dataclasses.replace(self.options, refresh_rate=0.0))
        try:
            gate.capture_background(frames[:1])
            moved = [i for i, f in enumerate(frames[1:], 1) if (r := gate.update(f)).contact or r.mismatch]
        except FrameError:
            return  # the runtime reports bad frames itself
        if moved:
            self.warn(f"sensor '{self.sensor}': frames {moved} of the {len(frames)} used to learn the background "
                      "already differ like contact; the background may hold a press: give a no-contact image "
                      "(--background / background = ...) or restart with the sensor untouched")

    def close(self) -> None:
        self.source.close()


@dataclass
class BuiltScene:
    runtime: Any  # ForceRuntime
    sinks: list
    notes: list[str]

    def close(self) -> None:
        """Close the runtime (sources and model) and every output; safe to call twice."""
        try:
            self.runtime.close()
        finally:
            for s in self.sinks:
                s.close()


def build_scene(scene: Scene, clock: Clock | None = None, warn: Callable[[str], None] | None = None) -> BuiltScene:
    """Open sources, gates, model (and depth stages only for depth bundles) and outputs.

    warn: called with a message when a learnt background already looks like contact
    (default: added to the notes of the result, see :class:`LearningWatch`)."""
    import time

    from .runtime import ForceRuntime, RuntimeOptions, Sensor, build_depth_stage
    from .sources import load_background

    clock = clock or time.monotonic_ns
    notes: list[str] = []
    warn = warn or notes.append
    backgrounds = {s.name: load_background(s.background) for s in scene.sensors if s.background is not None}
    model, backend, model_notes = load_model(scene)
    notes += model_notes
    sensors: list = []
    runtime = None
    try:
        for s in scene.sensors:
            gate = ContactGate(dataclasses.replace(s.gate))
            source = open_source(s, clock)
            if s.name in backgrounds:
                gate.capture_background(backgrounds[s.name], origin=str(s.background))
            else:
                notes.append(f"sensor '{s.name}': learning the background from the first "
                             f"{s.gate.background_frames} frames: keep the sensor untouched")
                source = LearningWatch(source, s.name, s.gate, warn)
            sensors.append(Sensor(s.name, source, gate))
        opts = RuntimeOptions(deadline_ms=scene.deadline_ms, threads=scene.threads, report_stale=scene.report_stale)
        runtime = ForceRuntime(sensors, model, opts, clock=clock, backend=backend, owns_model=True,
                               depth_factory=lambda: build_depth_stage(
                                   scene.depth, getattr(getattr(model, "bundle", None), "manifest", None)))
        for why in runtime.check_backgrounds().values():  # a given background that holds a press
            if why:
                warn(why)
        for sensor in runtime.sensors:
            # Paper depth mode: the zero-depth reference is the gate's background. Given as an
            # image, it is set here; learnt from frames, the runtime sets it once learnt.
            if sensor.depth is not None and getattr(sensor.depth, "needs_reference", False) \
                    and sensor.name in backgrounds:
                sensor.depth.set_reference(backgrounds[sensor.name])
        sinks = open_outputs(scene, p99_ms=lambda: runtime.latency()["total"]["p99"])
    except BaseException:
        if runtime is not None:
            runtime.close()
        else:
            for sensor in sensors:
                sensor.source.close()
            close = getattr(model, "close", None)
            if close is not None:
                close()
        raise
    return BuiltScene(runtime, sinks, notes)
