"""What a scene is: the typed records a scene file (or the command line) becomes.

:class:`SceneFile` is the TOML document's shape ([runtime], [gate], [depth], [[sensor]],
[[output]]); :mod:`.read` reads it with the package's one typed reader
(:mod:`tactile_force.edge.typed_json`), from the types and constraints declared here,
into a :class:`Scene`. A sensor table's keys depend on its source kind (:mod:`.kinds`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, Literal

from ..frames import MAX_BATCH
from ..gate.options import GateOptions
from ..typed_json import check

Backend = Literal["cpu", "oak"]
OutputKind = Literal["stdout", "csv", "jsonl", "mcap", "ros2", "zenoh"]
ZenohMode = Literal["client", "peer"]
DepthMode = Literal["exact", "paper"]
BACKENDS: tuple[str, ...] = ("cpu", "oak")
OUTPUT_KINDS: tuple[str, ...] = ("stdout", "csv", "jsonl", "mcap", "ros2", "zenoh")
#: The keys only a ``zenoh`` output takes.
ZENOH_KEYS = ("endpoint", "mode", "namespace", "node", "retry")
#: Output kinds that write a file (need ``path``).
FILE_OUTPUTS = ("csv", "jsonl", "mcap")
DEPTH_MODES: tuple[str, ...] = ("exact", "paper")
PACKAGE_DIR = Path(__file__).resolve().parent.parent  # the installed tactile_force/edge
#: ``package:FILE`` in a scene names a file shipped in tactile_force/edge/assets.
PACKAGE_PREFIXES = {"package:": PACKAGE_DIR / "assets"}

Clock = Callable[[], int]


def default_bundle_path() -> Path:
    """Where the embedded default bundle lives: <package>/models/default."""
    return PACKAGE_DIR / "models" / "default"


def shipped_bundles() -> dict[str, Path]:
    """The bundles shipped in the package, by folder name, the default first.

    Returns
    -------
    dict[str, pathlib.Path]
        ``{"default": .../models/default, "d": ..., "rgbmod_d": ..., "rgbmod_int8": ...}`` in this
        install: every folder of ``<package>/models`` holding a ``model.json`` (the default, a
        small fp32 RGBmod; an int8 RGBmod, and int8 D and RGBmod+D bundles; all trained on the
        virtual DIGIT's synthetic frames only). Empty when none is installed.
    """
    root = default_bundle_path().parent
    found = sorted(p for p in root.iterdir() if p.is_dir() and (p / "model.json").is_file()) if root.is_dir() else []
    found.sort(key=lambda p: p.name != "default")  # stable: the default first, the rest by name
    return {p.name: p for p in found}


# -- typed records ------------------------------------------------------------------------
@dataclass
class SensorSpec:
    """One [[sensor]] table after validation. Which fields a kind uses, and their
    defaults, come from its source kind (:func:`.kinds.kind_of`); paths are absolute."""

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


def ros2_topic_ok(topic: str) -> bool:
    """A ROS 2 topic name such as '/tactile/force': non-empty, no spaces."""
    return bool(topic) and " " not in topic


@dataclass
class OutputSpec:
    """One [[output]] table. path: absolute (file outputs), relative to the working
    directory in the file; topic: ROS 2 topic (ros2; zenoh: default 'tactile/force', a
    relative name resolved under ``namespace``); frames / mask: also log each gated
    frame (JPEG) / its contact mask (PNG) (mcap only); endpoint, mode, namespace, node,
    retry: the Zenoh router's locator (default tcp/localhost:7447), 'client' or 'peer', the
    node's namespace and name, keep running while the router is tried again (zenoh only)."""

    kind: OutputKind
    path: Path | None = field(default=None, metadata=check(
        path="output", expected="a file path (relative to the working directory)"))
    live: bool = False
    fsync: bool = False
    topic: str | None = field(default=None, metadata=check(
        test=ros2_topic_ok, expected="a ROS 2 topic name such as '/tactile/force'"))
    frames: bool = False
    mask: bool = False
    endpoint: str | None = field(default=None, metadata=check(
        test=lambda e: bool(e) and " " not in e, expected="a Zenoh locator such as 'tcp/localhost:7447'"))
    mode: ZenohMode = "client"
    namespace: str = field(default="/", metadata=check(
        test=lambda n: n.startswith("/") and " " not in n, expected="'/' or an absolute name such as '/left_hand'"))
    node: str = field(default="tactile_force", metadata=check(
        test=lambda n: bool(n) and " " not in n, expected="a ROS 2 node name such as 'tactile_force'"))
    retry: bool = False

    def check(self) -> None:
        """Rules across keys, and the topic made absolute (the typed reader calls it after
        reading the keys); ValueError naming the key."""
        if self.kind in FILE_OUTPUTS and self.path is None:
            raise ValueError(f"output '{self.kind}' needs 'path' (a file, relative to the working directory)")
        if self.kind not in FILE_OUTPUTS and self.path is not None:
            raise ValueError(f"output '{self.kind}' writes no file; remove 'path'")
        if self.kind == "ros2" and self.topic is None:
            raise ValueError("output 'ros2' needs 'topic' (e.g. '/tactile/force')")
        if self.kind == "zenoh":
            from ..outputs.zenoh_topic import (  # no Zenoh import there until a session opens
                DEFAULT_TOPIC,
                check_endpoint,
                check_node_name,
                resolve_topic,
            )

            self.topic = resolve_topic(DEFAULT_TOPIC if self.topic is None else self.topic, self.namespace,
                                       check_node_name(self.node))
            if self.endpoint is not None:
                self.endpoint = check_endpoint(self.endpoint)
        else:
            defaults = {f.name: f.default for f in fields(OutputSpec)}
            given = [k for k in ZENOH_KEYS if getattr(self, k) != defaults[k]]
            if given:
                raise ValueError(f"'{given[0]}' is for kind = \"zenoh\" only")
        if self.topic is not None:
            from ..outputs.ros2_names import ros_topic  # no DDS dependency

            self.topic = ros_topic(self.topic, "topic")  # made absolute; SceneError (a ValueError) if invalid
        for k in ("frames", "mask"):
            if getattr(self, k) and self.kind != "mcap":
                raise ValueError(f"'{k}' is for kind = \"mcap\" only; output '{self.kind}' writes readings")


@dataclass
class DepthSettings:
    """The scene's [depth] table: the DepthOptions fields the scene sets; None = not set
    (then the bundle manifest's :class:`~tactile_force.edge.bundle.manifest.DepthRecord`, else
    the DepthOptions default: :func:`tactile_force.edge.runtime.depth_factory.depth_options_for` merges
    them by field name). mapping: absolute (``package:FILE`` = a file in edge/assets)."""

    mapping: Path | None = field(default=None, metadata=check(
        expected="the colour->normal .npz (a path, or package:FILE for a file in edge/assets)"))
    mode: DepthMode | None = None
    levels_per_px: float | None = field(default=None, metadata=check(gt=0))
    paper_scale: float | None = field(default=None, metadata=check(gt=0))
    gel_width_m: float | None = field(default=None, metadata=check(gt=0))
    gel_height_m: float | None = field(default=None, metadata=check(gt=0))
    saturated_fraction: float | None = field(default=None, metadata=check(ge=0, le=1))
    solver_dtype: Literal["float32", "float64"] | None = None
    mapping_step: Literal[1, 2] | None = None
    paper_dilation_px: int | None = field(default=None, metadata=check(ge=0))

    def given(self) -> dict[str, Any]:
        """The keys the scene set (not None), in field order."""
        return {k: v for k, v in vars(self).items() if v is not None}


@dataclass
class RuntimeSettings:
    """The scene's [runtime] table. bundle: a path (relative to the scene file),
    "default" (the embedded model), or a list of paths (a ladder)."""

    bundle: str | list[str] = field(default="default", metadata=check(
        nonempty=True, expected='a path, "default", or a list of paths (ladder)'))
    backend: Backend = "cpu"
    fallback: Literal["cpu"] | None = field(default=None, metadata=check(expected='"cpu" (or leave it out)'))
    deadline_ms: float = field(default=16.7, metadata=check(gt=0))
    threads: int = field(default=1, metadata=check(ge=1))
    max_frames: int = field(default=0, metadata=check(ge=0, expected="an integer >= 0 (0 = until the sources end)"))
    report_stale: bool = True
    oak_archive: Path | None = field(default=None, metadata=check(
        expected="the NN Archive (.tar.xz) of the bundle for the OAK"))
    oak_device: str | None = None

    def check(self) -> None:
        if self.backend == "oak" and self.oak_archive is None and self.fallback != "cpu":
            raise ValueError("backend 'oak' needs 'oak_archive' (the bundle's NN Archive .tar.xz), "
                             "or fallback = \"cpu\"")


@dataclass(kw_only=True)
class SensorKeys:
    """The keys every [[sensor]] table has; each source kind adds its own in a subclass
    (:mod:`.kinds`). name: default ``sensorN`` (N = the table's index); gate: GateOptions
    fields overriding the kind's preset and the scene's [gate] table."""

    source: str
    name: str | None = field(default=None, metadata=check(nonempty=True))
    background: Path | None = field(default=None, metadata=check(expected="a no-contact image file or folder"))
    gate: dict[str, Any] = field(default_factory=dict, metadata=check(expected="a table of GateOptions fields"))


@dataclass
class SceneFile:
    """A scene file's tables as the typed reader reads them. ``gate`` holds GateOptions
    fields and each ``sensor`` table the keys of its source kind: both are read in a second
    step (:func:`tactile_force.edge.scene.read.parse_scene`), against the kind's preset."""

    runtime: RuntimeSettings = field(default_factory=RuntimeSettings)
    gate: dict[str, Any] = field(default_factory=dict)
    depth: DepthSettings = field(default_factory=DepthSettings)
    sensor: list[Any] = field(default_factory=list, metadata=check(expected=f"[[sensor]] tables (1 to {MAX_BATCH})"))
    output: list[OutputSpec] = field(default_factory=list, metadata=check(expected="[[output]] tables"))


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
    depth: DepthSettings = field(default_factory=DepthSettings)
    outputs: list[OutputSpec] = field(default_factory=list)

    @property
    def origin(self) -> str:
        """Where the scene came from, for messages: the file, or 'command line'."""
        return str(self.path) if self.path is not None else "command line"
