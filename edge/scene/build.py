"""Building a scene: the model, the sources and gates, the runtime and the outputs."""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import AcceleratorUnavailableError, SceneError, SourceError
from ..gate import ContactGate, GateOptions
from .kinds import open_source
from .model import Clock, Scene


def load_model(scene: Scene) -> tuple[Any, str, list[str]]:
    """(model, backend actually used, notes) for the scene's bundle(s) and backend."""
    from ..model.ladder import choose_bundle
    from ..model.onnx_model import LOAD_BATCH, OnnxForceModel

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
        model, choice = choose_bundle(ladder, scene.deadline_ms, threads=scene.threads,
                                      batch=max(LOAD_BATCH, len(scene.sensors)))  # every sensor in contact
        notes.append(choice.reason)
        return model, "cpu", notes
    return OnnxForceModel(scene.bundles[0], threads=scene.threads), "cpu", notes


def open_outputs(scene: Scene, p99_ms=None) -> list:
    """One writer per [[output]], in the scene's order; MCAP, ROS 2 and Zenoh writers are
    imported only when used. The networked ones are opened first, so one that cannot start (no
    Zenoh router) leaves no file output behind."""
    from ..outputs import CsvWriter, JsonlWriter, StdoutWriter

    sinks: list = []
    opened: dict[int, object] = {}
    order = sorted(range(len(scene.outputs)), key=lambda i: scene.outputs[i].kind not in ("ros2", "zenoh"))
    try:
        for i in order:
            o = scene.outputs[i]
            path = o.path if o.path is not None else Path(os.devnull)  # file outputs always have one
            if o.kind == "csv":
                sinks.append(CsvWriter(path, fsync=o.fsync))
            elif o.kind == "jsonl":
                sinks.append(JsonlWriter(path, fsync=o.fsync))
            elif o.kind == "mcap":
                from ..outputs.mcap_log import McapWriter  # the 'mcap' extra, imported only now

                sinks.append(McapWriter(path, frames=o.frames, mask=o.mask, fsync=o.fsync))
            elif o.kind == "ros2":
                from ..outputs.ros2_topic import Ros2Publisher  # the 'ros2' extra, imported only now

                assert o.topic is not None  # parse_scene requires it
                sinks.append(Ros2Publisher(o.topic))
            elif o.kind == "zenoh":
                from ..outputs.zenoh_topic import ZenohPublisher  # the 'zenoh' extra, imported only now

                assert o.topic is not None  # OutputSpec.check resolves it
                sinks.append(ZenohPublisher(o.topic, namespace=o.namespace, node=o.node, endpoint=o.endpoint,
                                            mode=o.mode, retry=o.retry))
            else:
                sinks.append(StdoutWriter(live=o.live, p99_ms=p99_ms, every=4))
            opened[i] = sinks[-1]
    except BaseException:
        for s in sinks:
            s.close()
        raise
    return [opened[i] for i in range(len(scene.outputs))]


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
        from ..errors import FrameError

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
    (default: added to the notes of the result, see :class:`LearningWatch`).

    OpenCV runs the scene's ``threads`` threads (``cv2.setNumThreads``, process-wide): the
    gate's calls work on 80 x 60 images, where a thread pool only burns CPU (the benchmarks
    run the runtime with one OpenCV thread for the same reason)."""
    import time

    import cv2

    cv2.setNumThreads(scene.threads)
    from ..runtime import ForceRuntime
    from ..runtime.depth_factory import build_depth_stage
    from ..runtime.options import RuntimeOptions, Sensor
    from ..sources import load_background

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
