"""Reading a scene: a TOML file or command-line flags, through the package's one typed
reader (:mod:`tactile_force.edge.typed_json`), then the paths it names checked.

Every error is a :class:`~tactile_force.edge.errors.SceneError` naming the file (or
``command line``) and the dotted key, e.g.
``scene.toml: sensor[0].fps: expected a number > 0, got 'fast'``.
"""

from __future__ import annotations

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
from ..frames import MAX_BATCH
from ..gate.options import GateOptions
from ..typed_json import Check, TypedJsonError, expand_path, from_json, read_value
from .kinds import SOURCE_KINDS, SOURCES
from .model import (
    PACKAGE_DIR,
    PACKAGE_PREFIXES,
    Scene,
    SceneFile,
    SensorSpec,
    default_bundle_path,
)

_TABLE = "a table"
_SOURCE = Check(choices=SOURCES)


def _expand(value: str, flag: str) -> Path:
    """A path given by ``flag`` with ``~`` and ``$VARS`` expanded; SceneError naming the flag
    and the variable when one is not set (it would stay in the path as written)."""
    try:
        return expand_path(value)
    except ValueError as exc:
        raise SceneError(f"{flag}: {exc}") from None


def _out_path(value: str, flag: str = "--out") -> Path:
    """An output path: relative to the working directory, never the scene or package folder."""
    return _expand(value, flag).absolute()


def _gate(table: dict[str, Any], base: GateOptions, key: str) -> GateOptions:
    """``base`` with the GateOptions fields of ``table`` replaced (typed reader: keys, types
    and ranges; GateOptions checks the rules across fields when made); TypedJsonError naming ``key``."""
    return from_json(GateOptions, table, key, defaults=base, table=_TABLE)


def _sensor(raw: Any, i: int, gate_table: dict[str, Any], base: Path) -> SensorSpec:
    """One [[sensor]] table: its source kind first, then the kind's keys (typed reader)."""
    key = f"sensor[{i}]"
    if not isinstance(raw, dict):
        raise TypedJsonError(f"{key}: expected {_TABLE}, got {raw!r}"[:200])
    if "source" not in raw:
        raise TypedJsonError(f"{key}.source: missing; expected one of {', '.join(map(repr, SOURCES))}")
    kind = SOURCE_KINDS[read_value(str, raw["source"], f"{key}.source", _SOURCE)]
    keys = from_json(kind.keys, raw, key, base=base, table=_TABLE)
    preset = _gate(gate_table, kind.gate_preset(), "gate")
    values = {k: getattr(keys, k) for k in kind.key_names}
    if values.get("fps") is not None:
        values["fps"] = float(values["fps"])
    return SensorSpec(name=keys.name or f"sensor{i}", source=kind.name, background=keys.background,
                      gate=_gate(keys.gate, preset, f"{key}.gate"), **values)


def _device_key(s: SensorSpec) -> tuple[str, str] | None:
    """The device a live sensor table opens, as (what, which) to compare tables by: a DIGIT
    by its serial (or index), a V4L2 node (a camera index N is /dev/videoN), a GelSight Mini
    by its serial or index; None for file and virtual sources (two may read the same file)."""
    if s.source == "digit":
        return ("DIGIT", str(s.serial if s.serial is not None else 0))
    if s.source not in ("camera", "gelsight_mini"):
        return None
    dev = s.device
    if s.source == "camera" and isinstance(dev, int):
        dev = f"/dev/video{dev}"
    if isinstance(dev, str) and dev.startswith("/dev/"):
        return ("camera", dev)
    return (s.source, str(dev))


def _one_table_per_device(sensors: list[SensorSpec]) -> None:
    """TypedJsonError naming the key when two [[sensor]] tables open the same device (two
    DIGITs with one serial, one /dev/videoN twice): they would fight over one camera."""
    seen: dict[tuple[str, str], int] = {}
    for i, s in enumerate(sensors):
        key = _device_key(s)
        if key is None:
            continue
        if key in seen:
            j = seen[key]
            field_name = "serial" if s.source == "digit" else "device"
            raise TypedJsonError(f"sensor[{i}].{field_name}: {key[0]} {key[1]!r} is also sensor[{j}] "
                                 f"({sensors[j].name}); expected one [[sensor]] table per device")
        seen[key] = i


def _bundles(bundle: str | list[str], base: Path) -> list[Path]:
    items = bundle if isinstance(bundle, list) else [bundle]
    return [default_bundle_path() if b == "default"
            else read_value(Path, b, "runtime.bundle" + (f"[{i}]" if isinstance(bundle, list) else ""), base=base)
            for i, b in enumerate(items)]


def parse_scene(data: dict, path: Path | None, base: Path | None = None) -> Scene:
    """Validate a parsed scene (types, ranges, finite numbers, unknown keys) with the typed
    reader; SceneError names the file and the dotted key.

    Parameters
    ----------
    data
        The parsed TOML document (or the same shape built from command-line flags).
    path
        The scene file (None for a command-line scene).
    base
        The folder input paths are relative to (default: the scene file's folder, else the
        working directory). Output paths are relative to the working directory.

    Returns
    -------
    The :class:`Scene`, paths absolute.
    """
    where = str(path) if path is not None else "command line"
    base = base or (path.parent if path is not None else Path.cwd())
    try:
        doc = from_json(SceneFile, data, base=base, prefixes=PACKAGE_PREFIXES, table=_TABLE)
        _gate(doc.gate, GateOptions(), "gate")  # keys and types, once
        if not doc.sensor:
            raise TypedJsonError(f"sensor: no [[sensor]] tables; expected 1 to {MAX_BATCH} sensors")
        if len(doc.sensor) > MAX_BATCH:
            raise TypedJsonError(f"sensor: {len(doc.sensor)} [[sensor]] tables; expected 1 to {MAX_BATCH} (one "
                                 f"runtime serves at most {MAX_BATCH} sensors: every frame needs its own gate pass, "
                                 f"and {MAX_BATCH} at 60 fps fill one core; split them over two scenes)")
        sensors = [_sensor(t, i, doc.gate, base) for i, t in enumerate(doc.sensor)]
        if len({s.name for s in sensors}) != len(sensors):
            raise TypedJsonError(f"sensor: names {[s.name for s in sensors]} must be unique")
        _one_table_per_device(sensors)
        rt = doc.runtime
        bundles = _bundles(rt.bundle, base)
    except TypedJsonError as exc:
        raise SceneError(f"{where}: {exc}") from None
    return Scene(path=path, sensors=sensors, bundles=bundles, backend=rt.backend, fallback=rt.fallback,
                 deadline_ms=rt.deadline_ms, threads=rt.threads, max_frames=rt.max_frames,
                 report_stale=rt.report_stale, oak_archive=rt.oak_archive, oak_device=rt.oak_device,
                 depth=doc.depth, outputs=doc.output)


# -- paths -----------------------------------------------------------------------------------
def path_kind(p: Path) -> str:
    """What ``p`` is, in words: 'a regular file', 'a folder', 'a FIFO' (socket, device), 'a
    symbolic link to a missing ...', or 'not found' (for messages saying what was found)."""
    from ..files.guard import special_file_kind

    if not p.exists():
        return f"a symbolic link to a missing {os.readlink(p)}" if p.is_symlink() else "not found"
    if p.is_dir():
        return "a folder"
    if (special := special_file_kind(p)) is not None:
        return f"a {special}"
    return "a regular file" if p.is_file() else "not a regular file"


def _readable(p: Path, want: str) -> str | None:
    """Why ``p`` cannot be read as ``want`` ('file', 'folder' or 'file or folder'), else None."""
    if not p.exists():
        return f"{p} not found" if not p.is_symlink() else f"{p} is {path_kind(p)}"
    if want == "file" and not p.is_file():
        return f"{p} is {path_kind(p)}; expected a regular file"
    if want == "folder" and not p.is_dir():
        return f"{p} is {path_kind(p)}; expected a folder"
    if want == "file or folder" and (kind := path_kind(p)) not in ("a regular file", "a folder"):
        return f"{p} is {kind}; expected a regular file or a folder"
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
    for i, b in enumerate(scene.bundles):
        key = "runtime.bundle" + (f"[{i}]" if len(scene.bundles) > 1 else "")
        if (p := _readable(b, "folder")) or (p := _readable(b / "model.json", "file")):
            out.append(f"{where}: {key}: {p} (expected a bundle folder with model.json)")
    if (scene.backend == "oak" and scene.oak_archive is not None and scene.fallback != "cpu"
            and (p := _readable(scene.oak_archive, "file"))):
            out.append(f"{where}: runtime.oak_archive: {p} (or set fallback = \"cpu\" to run on the CPU without it)")
    if scene.depth.mapping is not None and (p := _readable(scene.depth.mapping, "file")):
        out.append(f"{where}: depth.mapping: {p}")
    for i, s in enumerate(scene.sensors):
        ws = f"{where}: sensor[{i}] ({s.name})"
        if s.path is not None:
            want = "folder" if s.source == "replay" else "file"
            if p := _readable(s.path, want):
                out.append(f"{ws}.path: {p}")
        if s.background is not None and (p := _readable(s.background, "file or folder")):
            out.append(f"{ws}.background: {p}")
    paths = [o.path for o in scene.outputs if o.path is not None]
    for i, o in enumerate(scene.outputs):
        if o.path is None:
            continue
        if paths.count(o.path) > 1:
            out.append(f"{where}: output[{i}].path: {o.path} is used by more than one output")
        elif p := output_problem(o.path):
            out.append(f"{where}: output[{i}].path: {p}")
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
    kind = path_kind(p)
    if kind != "a regular file":
        raise SceneError(f"{p}: scene file {kind if kind == 'not found' else 'is ' + kind}; expected a regular TOML "
                         "file (a scene, e.g. edge/scenes/replay_rgbmod.toml)")
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
    p = _expand(source, "--source")
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
                     fps: float | None = None, live_status: bool = False, mcap_frames: bool = False,
                     depth_mapping: str | None = None, zenoh: dict[str, Any] | None = None) -> Scene:
    """The Scene a TOML file with these settings would give, read by the same typed reader
    (errors name ``command line`` and the key). mcap_frames: the .mcap outputs also log each
    frame and its contact mask; depth_mapping: the [depth] mapping (relative to the working
    directory, or ``package:FILE``); zenoh: the keys of a ``zenoh`` output (endpoint, topic,
    mode, namespace, node, retry; None: no Zenoh output)."""
    sensor = {"name": name, **source_table(source)}
    if background is not None:
        sensor["background"] = str(_expand(background, "--background").absolute())
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
    if zenoh is not None:
        outs.append({"kind": "zenoh", **{k: v for k, v in zenoh.items() if v is not None}})
    outs.insert(0, {"kind": "stdout", "live": live_status})
    data: dict[str, Any] = {
        "runtime": {"bundle": bundle if bundle == "default" else str(_expand(bundle, "--bundle").absolute())},
        "sensor": [sensor], "output": outs}
    if depth_mapping is not None:
        data["depth"] = {"mapping": depth_mapping}
    return parse_scene(data, None, Path.cwd())
