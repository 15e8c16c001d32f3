"""Reading a scene: a TOML file or command-line flags, validated; the paths it names checked."""

from __future__ import annotations

import dataclasses
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Any

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.10: the same parser from PyPI (a core dependency there)
    import tomli as tomllib

from ..errors import SceneError
from ..gate import GateOptions
from ..runtime import resolve_package_path
from .kinds import _COMMON_SENSOR_KEYS, SOURCE_KINDS, SOURCES
from .model import (
    BACKENDS,
    DEPTH_MODES,
    FILE_OUTPUTS,
    OUTPUT_KINDS,
    PACKAGE_DIR,
    Key,
    OutputSpec,
    Scene,
    SensorSpec,
    _finite_pos,
    default_bundle_path,
)


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
        from ..outputs.ros2_names import ros_topic  # no DDS dependency

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
