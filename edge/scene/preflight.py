"""Every check ``tactile-force run`` makes of a scene before it opens a device or loads the
model, in one function (:func:`run_refusals`) that ``run`` and ``scene show`` both call, so
``scene show`` answers (exit code and message) as ``run`` would.

The checks, each a message naming the file and the key:

- inputs missing and outputs that cannot be written (:func:`~.read.scene_problems`);
- the output guard for a scene file's reading files: an existing output needs ``--force``,
  and no output may be or lie inside an input (the scene file, a bundle, a replay folder,
  a background);
- bundles that cannot be loaded, and the depth stage of a depth bundle;
- what each sensor's source would refuse at once: a background image of another size, a
  replay folder or video file that cannot be opened (a dangling link, frames the runtime
  would refuse), a camera, DIGIT or GelSight Mini that is not attached (only where ``run``
  would refuse it at once: a /dev node that does not exist, a serial USB discovery does not
  list). No device is opened, no frame is read from a device.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

from ..errors import SourceError, TactileForceError
from .kinds import kind_of
from .model import Scene, SensorSpec


def depth_problems(scene: Scene) -> list[str]:
    """Why the depth stage of a depth-bundle scene could not be built (mapping missing,
    paper mode with a LUT, bad options), one message each; [] for RGB-only bundles."""
    from ..bundle.store import load_bundle
    from ..errors import BundleError, SceneError
    from ..runtime.depth_factory import build_depth_stage

    out = []
    for b in scene.bundles:
        try:
            bundle = load_bundle(b)
        except BundleError:
            continue  # reported by bundle_problems
        if not bundle.manifest.needs_depth:
            continue
        try:
            build_depth_stage(scene.depth, bundle.manifest)
        except SceneError as exc:  # names the key: depth.mapping, depth
            out.append(f"{scene.origin}: {exc}")
        except Exception as exc:  # noqa: BLE001 - any reason the stage cannot be built is a problem to show
            out.append(f"{scene.origin}: depth: {exc}")
        break
    return out


def scene_inputs(scene: Scene, scene_file: str | os.PathLike | None) -> list[tuple[str, str | os.PathLike | None]]:
    """Every path a scene reads, as (what gave it, path): the scene file, its bundles, depth
    mapping, replay folders and backgrounds. No output may be, hold or lie inside one of them."""
    inputs: list[tuple[str, str | os.PathLike | None]] = [("--scene", scene_file)]
    inputs += [("bundle", b) for b in scene.bundles if str(b) != "default"]
    inputs.append(("depth mapping", getattr(scene.depth, "mapping", None)))
    for s in scene.sensors:
        inputs += [(f"sensor {s.name} path", s.path), (f"sensor {s.name} background", s.background)]
    return inputs


def output_refusals(scene: Scene, scene_file: str | os.PathLike, force: bool = False) -> list[str]:
    """The output guard for a scene file's file outputs (csv, jsonl, mcap): an existing file
    needs ``force``, and no output may be or lie inside one of the scene's inputs (the scene
    file, its bundles, replay folders, backgrounds). One message per refused output."""
    from ..files.guard import OutputKind, OutputRefused, check_output

    inputs = scene_inputs(scene, scene_file)
    out = []
    for k, o in enumerate(scene.outputs):
        if o.path is not None and o.kind in ("csv", "jsonl", "mcap"):
            try:
                check_output(o.path, inputs, force=force, kind=OutputKind.FILE, flag=f"{scene_file}: output[{k}].path")
            except OutputRefused as exc:
                out.append(str(exc))
    return out


def _device_problem(s: SensorSpec) -> str | None:
    """Why ``run`` would refuse a live sensor at once because its device is not there (a
    /dev node that does not exist, a serial USB discovery does not list), else None."""
    from ..sources import missing_camera

    if s.source == "camera":
        return missing_camera(s.device)
    if s.source not in ("digit", "gelsight_mini"):
        return None
    from tactile_force.firmware_bridge.discovery import find_digit, find_gelsight_mini, locate_sensor

    sensor = (s.serial if s.serial is not None else 0) if s.source == "digit" else s.device
    try:
        _, node = locate_sensor(sensor, find_digit if s.source == "digit" else find_gelsight_mini)
    except SourceError as exc:
        return str(exc)
    return missing_camera(node) if node else None


def source_problems(scene: Scene) -> list[str]:
    """What each sensor's source would refuse at once when ``run`` opens it (see the module
    docstring); paths that do not exist are left to :func:`~.read.scene_problems`."""
    from ..sources import ReplayFolderSource, VideoFileSource, load_background

    out = []
    for i, s in enumerate(scene.sensors):
        where = f"{scene.origin}: sensor[{i}] ({s.name})"
        if s.background is not None and s.background.exists():
            try:
                load_background(s.background)
            except SourceError as exc:
                out.append(f"{where}.background: {exc}")
        try:
            if s.source == "replay" and s.path is not None and s.path.is_dir():
                ReplayFolderSource(s.path, name=s.name).close()
            elif s.source == "video" and s.path is not None and s.path.is_file():
                VideoFileSource(s.path, name=s.name).close()
        except SourceError as exc:
            out.append(f"{where}.path: {exc}")
        if kind_of(s).live and (why := _device_problem(s)) is not None:
            out.append(f"{where}: {why}")
    return out


def run_refusals(scene: Scene, scene_file: str | os.PathLike | None = None, force: bool = False) -> list[str]:
    """Every reason ``tactile-force run`` refuses ``scene`` before it opens a device or loads
    the model, one message each (file and key named); [] when it would start.

    Parameters
    ----------
    scene
        The parsed scene (:func:`~.read.load_scene` with ``check=False``, or from flags).
    scene_file
        The scene file as the user gave it: its file outputs go through the output guard
        (``--force`` = ``force``). None for a scene made from flags, whose ``--out`` files
        were guarded when it was made.
    force
        ``run --force``: existing outputs may be replaced (never an input).
    """
    from .describe import bundle_problems
    from .read import scene_problems

    out = scene_problems(scene)
    if scene_file is not None:
        out += output_refusals(scene, scene_file, force)
    present = dataclasses.replace(scene, bundles=[b for b in scene.bundles if Path(b).exists()])
    out += bundle_problems(present) + depth_problems(present)
    try:
        out += source_problems(scene)
    except TactileForceError as exc:  # e.g. a missing extra for a device's discovery
        out.append(f"{scene.origin}: {exc}")
    return out
