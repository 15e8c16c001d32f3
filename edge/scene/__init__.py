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
folder). ``~`` and ``$VARS`` are expanded; a variable that is not set is an error naming
the key and the variable. Every key is checked for type, range and (paths)
readability / writability by :func:`load_scene` before anything heavy is loaded, by the
package's one typed reader (:mod:`tactile_force.edge.typed_json`); errors name the file and
the dotted key, e.g. ``scene.toml: sensor[0].fps: expected a number > 0, got 'fast'``. No
device library (depthai, pyusb, hidapi) and no depth code is imported unless the scene
needs it.

Each source kind is one entry of :data:`SOURCE_KINDS`: its keys (a dataclass: types,
defaults, checks), its gate preset and its opener. Adding a kind means adding its keys
class and one entry.

The package, split by job: :mod:`.model` (what a scene is), :mod:`.read` (reading and
checking it), :mod:`.kinds` (the source-kind registry and its openers), :mod:`.describe`
(writing it back to TOML and describing it), :mod:`.preflight` (every check ``run`` makes
before it opens a device; ``scene show`` makes the same), :mod:`.build` (building it). The
public names are importable from here; the submodules are imported when one of their names
is first used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .model import (
    BACKENDS,
    DEPTH_MODES,
    FILE_OUTPUTS,
    OUTPUT_KINDS,
    PACKAGE_DIR,
    PACKAGE_PREFIXES,
    Backend,
    Clock,
    DepthMode,
    DepthSettings,
    OutputKind,
    OutputSpec,
    RuntimeSettings,
    Scene,
    SceneFile,
    SensorKeys,
    SensorSpec,
    default_bundle_path,
    ros2_topic_ok,
    shipped_bundles,
)

if TYPE_CHECKING:
    from .build import (
        BuiltScene,
        LearningWatch,
        build_scene,
        load_model,
        open_outputs,
    )
    from .describe import (
        bundle_problems,
        describe_scene,
        save_scene,
        scene_to_toml,
    )
    from .kinds import (
        SOURCE_KINDS,
        SOURCES,
        CameraKeys,
        DigitKeys,
        GelSightMiniKeys,
        ReplayKeys,
        SourceKind,
        VideoKeys,
        VirtualKeys,
        open_source,
        udev_watcher,
    )
    from .preflight import run_refusals
    from .read import (
        check_scene,
        load_scene,
        output_problem,
        output_table,
        parse_scene,
        scene_from_flags,
        scene_problems,
        source_table,
    )

#: name -> submodule, for the names imported on first use (the build code imports the
#: runtime; a scene is read and described without it)
_LAZY = {
    "CameraKeys": "kinds",
    "DigitKeys": "kinds",
    "GelSightMiniKeys": "kinds",
    "ReplayKeys": "kinds",
    "SOURCES": "kinds",
    "SOURCE_KINDS": "kinds",
    "SourceKind": "kinds",
    "VideoKeys": "kinds",
    "VirtualKeys": "kinds",
    "open_source": "kinds",
    "udev_watcher": "kinds",
    "run_refusals": "preflight",
    "check_scene": "read",
    "load_scene": "read",
    "output_problem": "read",
    "output_table": "read",
    "parse_scene": "read",
    "scene_from_flags": "read",
    "scene_problems": "read",
    "source_table": "read",
    "bundle_problems": "describe",
    "describe_scene": "describe",
    "save_scene": "describe",
    "scene_to_toml": "describe",
    "BuiltScene": "build",
    "LearningWatch": "build",
    "build_scene": "build",
    "load_model": "build",
    "open_outputs": "build",
}

__all__ = [
    "BACKENDS",
    "Backend",
    "BuiltScene",
    "CameraKeys",
    "Clock",
    "DEPTH_MODES",
    "DepthMode",
    "DepthSettings",
    "DigitKeys",
    "FILE_OUTPUTS",
    "GelSightMiniKeys",
    "LearningWatch",
    "OUTPUT_KINDS",
    "OutputKind",
    "OutputSpec",
    "PACKAGE_DIR",
    "PACKAGE_PREFIXES",
    "ReplayKeys",
    "RuntimeSettings",
    "SOURCES",
    "SOURCE_KINDS",
    "Scene",
    "SceneFile",
    "SensorKeys",
    "SensorSpec",
    "SourceKind",
    "VideoKeys",
    "VirtualKeys",
    "build_scene",
    "bundle_problems",
    "check_scene",
    "default_bundle_path",
    "describe_scene",
    "load_model",
    "load_scene",
    "open_outputs",
    "open_source",
    "output_problem",
    "output_table",
    "parse_scene",
    "ros2_topic_ok",
    "run_refusals",
    "save_scene",
    "scene_from_flags",
    "scene_problems",
    "scene_to_toml",
    "shipped_bundles",
    "source_table",
    "udev_watcher",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
        globals()[name] = value
        return value
    from .. import _moved

    return _moved.old_name(__name__, name)  # a name earlier versions had here (DeprecationWarning), or AttributeError


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
