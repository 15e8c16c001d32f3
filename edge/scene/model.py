"""What a scene is: the typed records a scene file or the command line becomes."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..gate import GateOptions

if TYPE_CHECKING:
    from .kinds import SourceKind


BACKENDS = ("cpu", "oak")
OUTPUT_KINDS = ("stdout", "csv", "jsonl", "mcap", "ros2")
#: Output kinds that write a file (need ``path``).
FILE_OUTPUTS = ("csv", "jsonl", "mcap")
DEPTH_MODES = ("exact", "paper")
PACKAGE_DIR = Path(__file__).resolve().parent.parent  # the installed tactile_force/edge

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
        from .kinds import SOURCE_KINDS

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
