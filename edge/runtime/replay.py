"""A labelled folder replayed through :class:`~tactile_force.edge.runtime.loop.ForceRuntime`
exactly as ``tactile-force run --source DATA --bundle BUNDLE --background BG`` builds it: the
readings that ``calibrate-force`` (depth bundles), ``study`` and ``bench --data`` measure."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..reading import ForceReading


def replay_readings(bundle: Path, data: Path, background: Path | None, threads: int = 1,
                    warn: Callable[[str], None] | None = None, calibrate: bool = True) -> list[ForceReading]:
    """The readings with truth of ``bundle`` on the labelled folder ``data``, replayed through
    the runtime ``tactile-force run`` builds.

    Parameters
    ----------
    bundle : Path
        The bundle folder.
    data : Path
        The labelled folder (the authors' layout: images/N.png + forces/force_N.txt).
    background : Path or None
        The no-contact image given to the gate (None: learnt from the first frames, as ``run``).
    threads : int
        ONNX Runtime intra-op threads.
    warn : callable or None
        Gets the scene's warnings (default: dropped).
    calibrate : bool
        False: the model's output is not put through the bundle's force calibration
        (``raw_force_n`` is then the raw estimate the runtime's inputs give, what
        ``calibrate-force`` fits on).

    Returns
    -------
    list of ForceReading
        The readings whose frame has a truth, in frame order.

    Raises
    ------
    TactileForceError
        A subclass (exit 2) when ``data``, ``background`` or ``bundle`` is unusable.
    """
    from ..scene import build_scene, check_scene, scene_from_flags

    scene = scene_from_flags(str(data), bundle=str(bundle), background=str(background) if background else None)
    scene.threads = threads
    scene = check_scene(scene)
    built = build_scene(scene, warn=warn or (lambda m: None))
    if not calibrate:
        built.runtime.model.calibration = None  # OnnxForceModel(calibrate=False)
    readings: list[ForceReading] = []
    try:
        built.runtime.run([], on_reading=lambda r: readings.append(r) if r.truth_n is not None else None)
    finally:
        built.close()
    return readings
