"""Scene files (TOML): what the setup is, and building only the stages it needs.

    [runtime]
    bundle = "default"        # a bundle path, "default" (the embedded model), or a list = ladder
    backend = "cpu"           # "cpu" | "oak"
    fallback = "cpu"          # optional: use the CPU when the OAK cannot be used
    deadline_ms = 16.7
    threads = 1
    max_frames = 0            # 0 = until the sources end

    [gate]                    # GateOptions fields, defaults for every sensor
    threshold = 14.0

    [depth]                   # DepthOptions fields (depth bundles only)

    [[sensor]]
    name = "left"
    source = "replay"         # "camera" | "replay" | "video" | "virtual" | "gelsight_mini"
    path = "grasp_01"         # replay folder / video file (relative to the scene file)
    device = 0                # camera index or /dev/videoN; gelsight_mini: serial, index or /dev/videoN
    fps = 60.0                # camera rate; for replay/video: pace at this rate (omit = as fast as read)
    background = "bg.png"     # optional no-contact image(s); else learnt from the first frames
    gate = { threshold = 14.0 }   # per-sensor overrides

    [[output]]
    kind = "csv"              # "stdout" | "csv" | "jsonl"
    path = "readings.csv"

Paths are relative to the scene file; ``~`` and ``$VARS`` are expanded. No device library
(depthai, pyusb, hidapi) and no depth code is imported unless the scene needs it.
"""

from __future__ import annotations

import dataclasses
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .errors import AcceleratorUnavailableError, BundleError, SceneError, SourceError
from .gate import ContactGate, GateOptions

SOURCES = ("camera", "replay", "video", "virtual", "gelsight_mini")
BACKENDS = ("cpu", "oak")
OUTPUT_KINDS = ("stdout", "csv", "jsonl")
_RUNTIME_KEYS = {"bundle", "backend", "fallback", "deadline_ms", "threads", "max_frames", "report_stale",
                 "oak_archive", "oak_device"}
_SENSOR_KEYS = {"name", "source", "path", "device", "fps", "background", "gate", "seed", "n_grasps"}
_OUTPUT_KEYS = {"kind", "path", "live", "fsync"}


def default_bundle_path() -> Path:
    """Where the embedded default bundle lives: <package>/models/default."""
    return Path(__file__).resolve().parent / "models" / "default"


@dataclass
class SensorSpec:
    name: str
    source: str
    path: Path | None = None
    device: int | str = 0
    fps: float | None = None
    background: Path | None = None
    gate: GateOptions = field(default_factory=GateOptions)
    seed: int = 0
    n_grasps: int = 3


@dataclass
class OutputSpec:
    kind: str
    path: Path | None = None
    live: bool = False
    fsync: bool = False


@dataclass
class Scene:
    """A parsed scene. bundles: one path, or several (a ladder, most accurate picked)."""

    path: Path
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


def _err(where: str, msg: str) -> SceneError:
    return SceneError(f"{where}: {msg}")


def _check_keys(table: dict, allowed: set[str], where: str) -> None:
    for k in table:
        if k not in allowed:
            raise _err(where, f"unknown key '{k}'; expected one of {sorted(allowed)}")


def _typed(table: dict, key: str, types: tuple, where: str, default: Any, expected: str) -> Any:
    if key not in table:
        return default
    v = table[key]
    if isinstance(v, bool) and bool not in types:
        raise _err(where, f"'{key}' = {v!r}; expected {expected}")
    if not isinstance(v, types):
        raise _err(where, f"'{key}' = {v!r}; expected {expected}")
    return v


def _path(base: Path, value: str) -> Path:
    p = Path(os.path.expandvars(os.path.expanduser(value)))
    return p if p.is_absolute() else (base / p)


def _gate_options(table: dict, base: GateOptions, where: str) -> GateOptions:
    names = {f.name for f in dataclasses.fields(GateOptions)}
    _check_keys(table, names, where)
    opts = dataclasses.replace(base, **table)
    try:
        opts.validate()
    except ValueError as exc:
        raise _err(where, str(exc)) from None
    return opts


def parse_scene(data: dict, path: Path) -> Scene:
    """Validate a TOML dict; SceneError names the key and the expected value."""
    where = str(path)
    base = path.parent
    _check_keys(data, {"runtime", "gate", "depth", "sensor", "output"}, where)
    rt = data.get("runtime", {})
    _check_keys(rt, _RUNTIME_KEYS, f"{where} [runtime]")
    w = f"{where} [runtime]"
    bundle = rt.get("bundle", "default")
    items = bundle if isinstance(bundle, list) else [bundle]
    if not items or not all(isinstance(b, str) and b for b in items):
        raise _err(w, f"'bundle' = {bundle!r}; expected a path, \"default\", or a list of paths (ladder)")
    bundles = [default_bundle_path() if b == "default" else _path(base, b) for b in items]
    backend = _typed(rt, "backend", (str,), w, "cpu", f"one of {BACKENDS}")
    if backend not in BACKENDS:
        raise _err(w, f"'backend' = {backend!r}; expected one of {BACKENDS}")
    fallback = _typed(rt, "fallback", (str,), w, None, '"cpu"')
    if fallback not in (None, "cpu"):
        raise _err(w, f"'fallback' = {fallback!r}; expected \"cpu\" (or leave it out)")
    deadline = float(_typed(rt, "deadline_ms", (int, float), w, 16.7, "a number of milliseconds > 0"))
    if not deadline > 0:
        raise _err(w, f"'deadline_ms' = {deadline}; expected a number of milliseconds > 0")
    threads = _typed(rt, "threads", (int,), w, 1, "an integer >= 1")
    if threads < 1:
        raise _err(w, f"'threads' = {threads}; expected an integer >= 1")
    max_frames = _typed(rt, "max_frames", (int,), w, 0, "an integer >= 0 (0 = until the sources end)")
    report_stale = _typed(rt, "report_stale", (bool,), w, True, "true or false")
    oak_archive = _typed(rt, "oak_archive", (str,), w, None, "the NN Archive (.tar.xz) of the bundle for the OAK")
    oak_device = _typed(rt, "oak_device", (str,), w, None, "an OAK device id")
    if backend == "oak" and oak_archive is None and fallback != "cpu":
        raise _err(w, "backend 'oak' needs 'oak_archive' (the bundle's NN Archive .tar.xz), or fallback = \"cpu\"")

    gate_base = _gate_options(data.get("gate", {}), GateOptions(), f"{where} [gate]")
    depth = data.get("depth", {})
    if not isinstance(depth, dict):
        raise _err(f"{where} [depth]", "expected a table of DepthOptions fields")
    if "mapping" in depth:
        depth = {**depth, "mapping": str(_path(base, str(depth["mapping"])))}

    raw_sensors = data.get("sensor", [])
    if not isinstance(raw_sensors, list) or not raw_sensors:
        raise _err(where, "no [[sensor]] tables; expected one or two sensors")
    if len(raw_sensors) > 2:
        raise _err(where, f"{len(raw_sensors)} [[sensor]] tables; expected one or two (one per finger)")
    sensors = []
    for i, t in enumerate(raw_sensors):
        ws = f"{where} [[sensor]] #{i + 1}"
        _check_keys(t, _SENSOR_KEYS, ws)
        kind = _typed(t, "source", (str,), ws, None, f"one of {SOURCES}")
        if kind not in SOURCES:
            raise _err(ws, f"'source' = {kind!r}; expected one of {SOURCES}")
        name = _typed(t, "name", (str,), ws, f"sensor{i}", "a name string")
        spath = _typed(t, "path", (str,), ws, None, "a path string")
        if kind in ("replay", "video") and spath is None:
            raise _err(ws, f"source '{kind}' needs 'path' (a {'folder' if kind == 'replay' else 'video file'})")
        device = _typed(t, "device", (int, str), ws, 0, "a camera index or a /dev/videoN path")
        fps = _typed(t, "fps", (int, float), ws, None, "a frame rate > 0")
        if fps is not None and not fps > 0:
            raise _err(ws, f"'fps' = {fps}; expected a frame rate > 0")
        bg = _typed(t, "background", (str,), ws, None, "a no-contact image file or folder")
        gate_tab = _typed(t, "gate", (dict,), ws, {}, "a table of GateOptions fields")
        sensors.append(SensorSpec(
            name=name, source=kind, path=_path(base, spath) if spath else None, device=device,
            fps=float(fps) if fps is not None else None, background=_path(base, bg) if bg else None,
            gate=_gate_options(gate_tab, gate_base, f"{ws} gate"),
            seed=_typed(t, "seed", (int,), ws, 0, "an integer"),
            n_grasps=_typed(t, "n_grasps", (int,), ws, 3, "an integer >= 1"),
        ))
    if len({s.name for s in sensors}) != len(sensors):
        raise _err(where, f"sensor names {[s.name for s in sensors]} must be unique")

    outputs = []
    for i, t in enumerate(data.get("output", [])):
        wo = f"{where} [[output]] #{i + 1}"
        _check_keys(t, _OUTPUT_KEYS, wo)
        kind = _typed(t, "kind", (str,), wo, None, f"one of {OUTPUT_KINDS}")
        if kind not in OUTPUT_KINDS:
            raise _err(wo, f"'kind' = {kind!r}; expected one of {OUTPUT_KINDS}")
        opath = _typed(t, "path", (str,), wo, None, "a file path")
        if kind != "stdout" and opath is None:
            raise _err(wo, f"output '{kind}' needs 'path'")
        outputs.append(OutputSpec(kind, _path(base, opath) if opath else None,
                                  _typed(t, "live", (bool,), wo, False, "true or false"),
                                  _typed(t, "fsync", (bool,), wo, False, "true or false")))
    return Scene(path=path, sensors=sensors, bundles=bundles, backend=backend, fallback=fallback,
                 deadline_ms=deadline, threads=threads, max_frames=max_frames, report_stale=report_stale,
                 oak_archive=_path(base, oak_archive) if oak_archive else None, oak_device=oak_device, depth=depth, outputs=outputs)


def load_scene(path: str | os.PathLike) -> Scene:
    """Read and validate a scene file."""
    p = Path(path)
    if not p.is_file():
        raise SceneError(f"{p}: scene file not found")
    try:
        data = tomllib.loads(p.read_text())
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise SceneError(f"{p}: not valid TOML ({exc})") from None
    return parse_scene(data, p.resolve())


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


def _source_line(s: SensorSpec) -> str:
    if s.source == "camera":
        return f"camera {s.device} via OpenCV V4L2 at {s.fps or 60:g} fps, newest frame only"
    if s.source == "gelsight_mini":
        return f"GelSight Mini {s.device} via OpenCV V4L2, cropped 1/7 per side, 320x240 portrait, newest frame only"
    if s.source == "virtual":
        return f"virtual DIGIT (seed {s.seed}, {s.n_grasps} grasps, {s.fps or 60:g} fps)"
    pace = f"paced at {s.fps:g} fps" if s.fps else "as fast as read"
    exists = "" if s.path and s.path.exists() else "  [MISSING]"
    return f"{s.source} {s.path} ({pace}){exists}"


def describe_scene(scene: Scene) -> list[str]:
    """Human lines: the stages that will run, in order. Loads no model, opens no device."""
    lines = [f"scene {scene.path}"]
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
        lines.append(f"  source:{s.name:<6} {_source_line(s)}")
        bg = f"background from {s.background}" if s.background else f"background = mean of first {s.gate.background_frames} frames"
        lines.append(f"  gate:{s.name:<8} threshold {s.gate.threshold:g}, on/off area {s.gate.on_area_frac:g}/"
                     f"{s.gate.off_area_frac:g}, downscale x{s.gate.downscale}, {bg}")
        if needs_depth:
            mapping = scene.depth.get("mapping", "from the bundle manifest, else MISSING: set [depth] mapping")
            lines.append(f"  depth:{s.name:<7} DepthStage (RGB -> normals -> gradients -> Poisson -> masked depth; "
                         f"mapping {mapping})")
    be = scene.backend + (f" {scene.oak_archive}" if scene.backend == "oak" else "")
    be += f" (fallback {scene.fallback})" if scene.fallback else ""
    lines.append(f"  inference    {be}, {scene.threads} thread(s), batch {len(scene.sensors)} when all in contact, "
                 f"deadline {scene.deadline_ms:g} ms")
    if not needs_depth:
        lines.append("  (no depth stage: RGB-only bundle)")
    for o in scene.outputs or [OutputSpec("stdout")]:
        lines.append(f"  output       {o.kind}{' ' + str(o.path) if o.path else ''}{' (live status line)' if o.live else ''}")
    return lines


# -- building -----------------------------------------------------------------------------
def open_source(s: SensorSpec, clock=None):
    """Open the FrameSource a sensor spec names (device libraries only for that device)."""
    import time

    from . import sources

    clock = clock or time.monotonic_ns
    if s.source == "camera":
        return sources.CameraSource(s.device, fps=s.fps or 60.0, name=s.name, clock=clock)
    if s.source == "replay":
        return sources.ReplayFolderSource(s.path, fps=s.fps, name=s.name, clock=clock)
    if s.source == "video":
        return sources.VideoFileSource(s.path, fps=s.fps, name=s.name, clock=clock)
    if s.source == "gelsight_mini":
        from tactile_force.firmware_bridge import gelsight  # USB sensor code, imported only now

        return gelsight.GelSightMiniSource(gelsight.GelSightMiniOptions(sensor=s.device, fps=s.fps or 25.0),
                                           name=s.name, clock=clock)
    try:
        from .synthetic import VirtualDigitSource
    except ImportError as exc:
        raise SceneError(f"sensor '{s.name}': source 'virtual' needs tactile_force.edge.synthetic.VirtualDigitSource, "
                         f"which this installation lacks ({exc})") from None
    return VirtualDigitSource(seed=s.seed, n_grasps=s.n_grasps, fps=s.fps or 60.0)


def load_model(scene: Scene) -> tuple[object, str, list[str]]:
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
                raise SceneError(f"{scene.path}: backend 'oak' unavailable ({exc}); "
                                 "set fallback = \"cpu\" in [runtime] to run on the CPU instead") from None
            notes.append(f"OAK unavailable ({exc}); falling back to the CPU")
    if len(scene.bundles) > 1:
        model, choice = choose_bundle(scene.bundles, scene.deadline_ms, threads=scene.threads)
        notes.append(choice.reason)
        return model, "cpu", notes
    return OnnxForceModel(scene.bundles[0], threads=scene.threads), "cpu", notes


def open_outputs(scene: Scene, p99_ms=None) -> list:
    from .outputs import CsvWriter, JsonlWriter, StdoutWriter

    sinks = []
    for o in scene.outputs:
        if o.kind == "csv":
            sinks.append(CsvWriter(o.path, fsync=o.fsync))
        elif o.kind == "jsonl":
            sinks.append(JsonlWriter(o.path, fsync=o.fsync))
        else:
            sinks.append(StdoutWriter(live=o.live, p99_ms=p99_ms, every=4))
    return sinks


@dataclass
class BuiltScene:
    runtime: Any  # ForceRuntime
    sinks: list
    notes: list[str]

    def close(self) -> None:
        self.runtime.close()
        for s in self.sinks:
            s.close()


def build_scene(scene: Scene, clock=None) -> BuiltScene:
    """Open sources, gates, model (and depth stages only for depth bundles) and outputs."""
    import time

    from .runtime import ForceRuntime, RuntimeOptions, Sensor, build_depth_stage
    from .sources import load_background

    clock = clock or time.monotonic_ns
    model, backend, notes = load_model(scene)
    sensors = []
    try:
        for s in scene.sensors:
            gate = ContactGate(dataclasses.replace(s.gate))
            if s.background is not None:
                gate.capture_background(load_background(s.background))
            sensors.append(Sensor(s.name, open_source(s, clock), gate))
    except BaseException:
        for s in sensors:
            s.source.close()
        raise
    opts = RuntimeOptions(deadline_ms=scene.deadline_ms, threads=scene.threads, report_stale=scene.report_stale)
    runtime = ForceRuntime(sensors, model, opts, clock=clock, backend=backend,
                           depth_factory=lambda: build_depth_stage(
                               scene.depth, getattr(getattr(model, "bundle", None), "manifest", None)))
    sinks = open_outputs(scene, p99_ms=lambda: runtime.latency()["total"]["p99"])
    return BuiltScene(runtime, sinks, notes)
