"""The latency-bounded loop: sources -> gates -> [depth] -> one batched inference -> readings.

One :meth:`ForceRuntime.step` reads the newest frame of every live sensor, gates it, runs
the depth stage (depth bundles only) and one ``predict`` call for all sensors in contact
(one batch of every touching sensor's frame), and returns one :class:`ForceReading` per frame:

- gate closed -> 0 N, ``no_contact``, the CNN is not run; while the gate still learns its
  background (detail "learning background") the frame is not judged: interval ``unknown``;
- frames a source skipped because a newer one arrived -> ``stale`` readings (force nan);
- a reading whose total latency exceeds ``deadline_ms`` -> ``late`` (still reported); total
  latency runs from the frame's arrival (``TimedFrame.arrival_ns``, stamped by the source
  when it had the frame; when read() returned it for a source that stamps none) to the
  finished reading; ``source_ms`` is the time read() took;
- wrong shape/dtype, NaN, empty, all-dark/all-white frame, a failed depth stage -> ``invalid_input``;
- estimate < 1 N -> ``below_range`` (clamped at 0); >= 15 N or gel saturation seen -> ``saturated``
  (clamped at 15 N, a lower bound);
- a frame the gate cannot judge -> ``background_mismatch`` (it no longer fits the background) or
  ``invalid_input`` (RGB order, uniform, noise burst, blurred), force nan, the CNN is not run;
  a frame outside the bundle's ``data_stats`` -> ``out_of_distribution`` (force kept), a contact
  beyond them -> ``saturated`` (docs/runtime.md, "Flags");
- a source that raises SourceError gives one ``invalid_input`` reading naming the error and
  is dropped; the other sensors keep being served.

The loop only orders the steps; each is one call per frame into the module that does it:
read (``prewarm.WarmUps``: in the loop's thread or from ``grabbers``, after a warm-up where
one pays), gate (``gating``), sensor watch (``sensor_watch``), depth (the sensor's depth
stage), one batched predict (the model), judge (``judging``, which applies the error bar of
``bounds``), count (``RuntimeStats.count``). ``options`` holds what a runtime is built from (options, sensors, the
:class:`~.options.ForceModel` protocol), ``sharing`` who closes a shared model,
``depth_factory`` the depth stage of depth bundles.

A runtime serves 1 to :data:`~tactile_force.edge.frames.MAX_BATCH` (16) sensors. Two or more
are read side by side: each sensor's ``read()`` runs in its own grabber thread, which holds
at most one frame read ahead, so no sensor waits for another's camera; a step serves every
sensor whose frame is there, those in contact in one batched predict (a slow or dead sensor
holds up no other). Each frame still gets its own gate pass; each reading keeps its own
sensor's name, frame index and time stamp. Frames ready together are gated on two threads
(``workers``, ``RuntimeOptions.workers``), which is safe because no source, gate or depth
stage serves two sensors (``ownership``, checked at construction).

Sinks that log frames or contact masks (the MCAP writer with ``frames`` / ``mask``) get each
gated frame and the gate's full-resolution mask through ``write_frame`` (:func:`frame_sinks`);
with none, no frame is copied and the full-resolution mask is not made. In paper depth mode
the zero-depth reference follows the gate's background, also when the gate re-learns it.

Latency per stage is in every reading and as rolling p50/p99 (:meth:`ForceRuntime.latency`).
Timing uses an injectable ``clock`` (ns) so tests drive it deterministically.
"""

from __future__ import annotations

import math
import time
import weakref
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..bundle.interval import ForceInterval
from ..checks import expect
from ..errors import ModelClosedError, OptionsError, SourceError
from ..frames import FRAME_SHAPE, TimedFrame
from ..gate.contact_gate import GateResult
from ..reading import Flags, ForceReading, StageLatency
from .depth_factory import build_depth_stage, depth_of, plan_stages
from .gating import GateStep
from .grabbers import Read as _Read
from .judging import Judge
from .options import (
    ForceModel,
    LatencyWindow,
    ReadingSink,
    RuntimeOptions,
    RuntimeStats,
    Sensor,
    check_runtime_args,
    frame_sinks,
    shares_reduction,
)
from .ownership import check_owned
from .prewarm import WarmUps
from .sensor_watch import SensorWatch, WatchReference
from .sharing import attach, detach
from .workers import Workers as _Workers
from .workers import worker_count

if TYPE_CHECKING:  # the depth code is imported only for depth bundles
    from ..depth import DepthResult, DepthStage

__all__ = ["ForceRuntime"]

_NO_FRAME = np.empty((0, 0, 3), np.uint8)


def _end_threads(warm: WarmUps, workers: _Workers | None) -> None:
    """Let a dropped runtime's grabber and worker threads end (no wait; they hold no runtime)."""
    if warm.grabbers is not None:
        warm.grabbers.stop(timeout_s=0.0)
    if workers is not None:
        workers.stop(timeout_s=0.0)


@dataclass(slots=True)
class _Lane:
    """One sensor's steps in a runtime: its gate step, its watch, and whether the model reads
    the gate's reduced image."""

    sensor: Sensor
    gating: GateStep
    watch: SensorWatch
    shared: bool
    # with warm-ups: its last frame, raw force and gate result when that frame went to the
    # model (None otherwise), what the next warm-up runs the judge, depth and model on
    last: tuple[TimedFrame, float, GateResult] | None = None


@dataclass(slots=True)
class _Pending:
    """One sensor's frame on its way through a step: admitted (read, stamped), gated (and
    depth) by :meth:`ForceRuntime._gate`, possibly on a worker thread, then settled in the
    loop's thread; a frame in contact waits for the step's one batched predict."""

    lane: _Lane
    tf: TimedFrame
    start_ns: int
    lat: StageLatency
    t1: int  # clock when the frame was read (the gate's time starts here without grabbers)
    frame: np.ndarray  # the frame gated, checked (empty until then)
    gate: GateResult | None = None  # None: the frame contract or its exposure refused it
    res: DepthResult | None = None  # the depth stage's result (depth bundles, frames in contact)
    depth: np.ndarray | None = None
    net: np.ndarray | None = None  # the gate's reduced image when the model reads it as it is


class ForceRuntime:
    """Serve force readings for 1 to :data:`~tactile_force.edge.frames.MAX_BATCH` (16) sensors
    from one model.

    sensors: 1 to 16 :class:`Sensor` (names unique, each with its own source, gate and
    depth stage: one part given to two sensors raises :class:`OptionsError` naming both;
    e.g. the fingertips of a hand). model: a
    :class:`~.options.ForceModel` (OnnxForceModel, the OAK backend; a model lacking one of
    its members is refused with :class:`~tactile_force.edge.errors.ArgumentTypeError` naming
    it); a closed model is refused (:class:`ModelClosedError`). One model may be shared by
    several runtimes and threads (OnnxForceModel serialises its calls). depth_factory:
    builds one depth stage per sensor for depth models (default :func:`build_depth_stage`
    from the bundle's manifest; a new stage per call). clock: monotonic ns; give sources the same clock.

    owns_model: whether :meth:`close` closes the model. True (default, what callers that
    load a model for this runtime want): the model is closed, but only once the last runtime
    using it has closed, so closing one of two runtimes sharing a model never breaks the
    other. False: this runtime never asks for the model to be closed (a model you keep using
    and close yourself; it is still closed when an owning runtime sharing it closes last).
    """

    def __init__(self, sensors: list[Sensor], model: ForceModel, options: RuntimeOptions | None = None,
                 clock: Callable[[], int] = time.monotonic_ns,
                 depth_factory: Callable[[], DepthStage] | None = None, backend: str = "cpu",
                 owns_model: bool = True) -> None:
        check_runtime_args(sensors, model, options, clock, depth_factory, backend, owns_model)
        bundle = model.bundle
        if model.closed:
            raise ModelClosedError(f"{bundle.path if bundle is not None else 'model'}: ForceRuntime was given a "
                                   "closed model; load the bundle again")
        names = [s.name for s in sensors]
        if len(set(names)) != len(names):
            raise OptionsError(f"ForceRuntime.sensors: names {names}; expected unique names")
        self.sensors = sensors if isinstance(sensors, list) else list(sensors)
        self.model = model
        self.owns_model = bool(owns_model)
        self._closed = False
        self.options = options or RuntimeOptions()
        self.clock = clock
        self.backend = backend
        self.needs_depth = bool(model.needs_depth)
        depths: list[DepthStage | None] = [s.depth for s in sensors]
        if self.needs_depth:
            from ..depth import DepthStage  # noqa: PLC0415 - depth bundles only

            manifest = bundle.manifest if bundle is not None else None
            factory = depth_factory or (lambda: build_depth_stage(None, manifest))
            depths = [expect(factory(), DepthStage, "ForceRuntime.depth_factory()",
                             "a DepthStage (e.g. build_depth_stage(settings, manifest))") for _ in sensors]
        check_owned(sensors, depths)  # no source, gate or depth stage serves two sensors
        for s, d in zip(sensors, depths):
            s.depth = d
        self.stages = plan_stages(names, self.needs_depth, backend)
        self.stats = RuntimeStats()
        self._window = LatencyWindow(self.options.latency_window)
        # The batch buffers, one row per sensor, allocated once (a step with one frame in
        # contact hands the model views, with several it copies into these).
        self._rgb = np.empty((len(sensors), *FRAME_SHAPE), np.uint8)
        grids = {s.depth.grid_frame_shape[:2] for s in sensors if s.depth is not None} if self.needs_depth else set()
        rows, cols = grids.pop() if len(grids) == 1 else FRAME_SHAPE[:2]  # the depth stages' grid (e.g. 80 x 60)
        self._depth = np.empty((len(sensors), rows, cols, 1), np.uint8)
        # One downscale per frame: a sensor whose gate reduces frames the way the model's
        # network input is reduced hands the gate's reduced image to ``predict_reduced``.
        shared = [shares_reduction(s.gate, model) for s in sensors]
        net_shape = model.rgb_shape
        self._net = (np.empty((len(sensors), *net_shape), np.uint8)
                     if any(shared) and net_shape is not None else None)
        #: threads that run a step's per-sensor work when several frames are ready (workers.py)
        self.workers = worker_count(self.options.workers, len(sensors), clock is time.monotonic_ns)
        self._workers = _Workers(self.workers, "-".join(names)[:40]) if self.workers > 1 else None
        #: (frames, masks) to keep for frame sinks; (False, False) = none kept (zero cost).
        self.tap: tuple[bool, bool] = (False, False)
        #: (sensor, timestamp ns, HxWx3 uint8 BGR copy or None, HxW uint8 0/255 mask copy or
        #: None) of the frames gated in the last step, when :attr:`tap` asks for them.
        self.tapped: list[tuple[str, int, np.ndarray | None, np.ndarray | None]] = []
        reference = WatchReference(model)  # the calibration's sensor, the bundle's no-contact image
        self._lanes = {s.name: _Lane(s, GateStep(s.name, s.gate), SensorWatch(s, reference), sh)
                       for s, sh in zip(sensors, shared)}
        self._judge = Judge(bundle)  # flags, honest force, error bar of every reading (judging.py)
        # The step's reads, and getting ready shortly before the next frame is due at a slow
        # cadence where it pays on this host (prewarm.py, prewarm_decision.py).
        self._warm = WarmUps(self.sensors, model, self._judge, self._lanes, self.options, clock, self.stats)
        weakref.finalize(self, _end_threads, self._warm, self._workers)  # dropped without close(): no thread left
        attach(model)  # last: a runtime that failed to build does not count as a user

    # -- public ---------------------------------------------------------------------------
    @property
    def finished(self) -> bool:
        return not any(s.alive for s in self.sensors)

    def latency(self) -> dict[str, dict[str, float]]:
        """Rolling p50/p99 per stage, ms."""
        return self._window.percentiles()

    @property
    def closed(self) -> bool:
        """True after :meth:`close` (step, start and run then raise :class:`ModelClosedError`)."""
        return self._closed

    @property
    def interval(self) -> ForceInterval | None:
        """The bundle's interval record applied to every reading (None: every reading's
        interval is ``unknown``: the manifest has none, or it was fitted for another model)."""
        return self._judge.interval

    def _check_open(self) -> None:
        if self._closed:
            raise ModelClosedError(f"ForceRuntime({', '.join(s.name for s in self.sensors)}) was closed: its sources "
                                   "and model are released; build a new runtime")

    def step(self) -> list[ForceReading]:
        """Process the newest frame of every live sensor; [] once every source has ended.
        Raises :class:`ModelClosedError` after :meth:`close`."""
        self._check_open()
        out: list[ForceReading] = []
        pending: list[_Pending] = []
        self.tapped.clear()
        live = [s for s in self.sensors if s.alive]
        if not live:
            return out
        reads = self._warm.read(live)  # read (after a warm-up where one pays: prewarm.py)
        self._acquire(reads, out, pending)  # gate, sensor watch, depth
        if pending:
            self._infer(pending, out)  # one batched predict, judge
        count = self.stats.count
        for r in out:
            count(r)
        self._warm.record(out)  # the 'auto' trial's window (prewarm_decision.py)
        return out

    def check_backgrounds(self) -> dict[str, str]:
        """Check every sensor's given background (``ContactGate.capture_background``) for a
        press now (the runtime also does on the first frame after one is given): sensor ->
        why it looks pressed, or "" (fine, or no reference in the bundle to check it against;
        edge/gate/given_background.py). While it looks pressed, the sensor's ``no_contact``
        readings carry ``background_mismatch`` and no force."""
        return {name: lane.watch.check_background() for name, lane in self._lanes.items()}

    def start(self, wait_s: float = 0.0) -> bool:
        """Start the grabber threads (step() does on its first call) and wait up to ``wait_s``
        seconds until every live sensor has a frame read, so the first step serves them all
        in one batch. True when they have (always True without grabber threads)."""
        self._check_open()
        if not self._warm.use_grabbers:
            return True
        return self._warm.start().wait_all([s for s in self.sensors if s.alive], wait_s)

    def run(self, sinks: Iterable[ReadingSink] = (), max_frames: int | None = None,
            on_reading: Callable[[ForceReading], None] | None = None) -> RuntimeStats:
        """Step until every source ends (or ``max_frames`` readings), writing each reading to
        every sink as it is made. Sinks that want frames or contact masks (:func:`frame_sinks`)
        get each gated frame's first, through ``write_frame`` (the gate's full-resolution
        mask is made only then). Returns the stats with rolling latency percentiles."""
        self._check_open()
        sinks = list(sinks)
        taps = frame_sinks(sinks)
        self.tap = (any(t.frames for t in taps), any(t.mask for t in taps))
        while not self.finished:
            readings = self.step()
            for name, ts, frame, mask in self.tapped:
                for t in taps:
                    t.write_frame(name, ts, frame, mask)
            for r in readings:
                for sink in sinks:
                    sink.write(r)
                if on_reading is not None:
                    on_reading(r)
            if max_frames is not None and self.stats.readings >= max_frames:
                break
        self.stats.latency_ms = self.latency()
        return self.stats

    def close(self) -> None:
        """Stop the grabber and worker threads, close every source, then the model when this
        runtime owns it and no other runtime still uses it (see ``owns_model``). Idempotent.

        Every part is released even when a source's ``close()`` raises: the model too; then
        :class:`SourceError` names each sensor whose source failed to close (the first
        failure chained)."""
        if self._closed:
            return
        self._closed = True
        failed: list[tuple[str, BaseException]] = []
        try:
            grabbers = self._warm.grabbers
            if grabbers is not None:
                grabbers.stop(timeout_s=0.0)
            for s in self.sensors:
                try:
                    s.source.close()
                except Exception as exc:  # noqa: BLE001 - the other sources and the model are still released
                    failed.append((s.name, exc))
            if grabbers is not None:
                grabbers.stop()
                self._warm.grabbers = None
            if self._workers is not None:
                self._workers.stop()
        finally:
            if detach(self.model, self.owns_model):
                self.model.close()
        if failed:
            raise SourceError("ForceRuntime.close(): the source of " + "; of ".join(
                f"sensor {name!r} failed to close ({type(exc).__name__}: {exc})" for name, exc in failed)
                + "; every other source and the model were released") from failed[0][1]

    # -- the steps of one frame -------------------------------------------------------------
    def _finish(self, r: ForceReading, start_ns: int) -> ForceReading:
        r.latency.total_ms = (self.clock() - start_ns) / 1e6
        if r.latency.total_ms > self.options.deadline_ms:
            r.flags |= Flags.LATE
        self._window.add(r.latency)
        return r

    def _acquire(self, reads: list[tuple[Sensor, _Read]], out: list[ForceReading],
                 pending: list[_Pending]) -> None:
        """Admit, gate, watch and (depth bundles) depth each read sensor's frame: a frame in
        contact goes to ``pending`` for the batched predict, any other frame's reading to
        ``out``. With two or more frames and workers (workers.py) the gate steps run on the
        workers at once; admission and readings stay in this thread, in sensor order."""
        workers = self._workers
        if workers is None or len(reads) < 2:
            for s, rd in reads:  # one thread: each sensor's frame from read to reading
                p = self._admit(s, rd, out)
                if p is not None:
                    self._gate(p)
                    if self._settle(p, out):
                        pending.append(p)
            return
        admitted = [p for s, rd in reads if (p := self._admit(s, rd, out)) is not None]
        workers.run(self._gate, admitted)
        pending += [p for p in admitted if self._settle(p, out)]

    def _admit(self, s: Sensor, r: _Read, out: list[ForceReading]) -> _Pending | None:
        """One sensor's read: a source error or the end of its stream ends the sensor, frames
        it skipped become ``stale`` readings (to ``out``); the frame read is returned."""
        if r.error is not None:
            exc = r.error
            s.alive, s.error = False, str(exc)
            self.stats.source_errors += 1
            out.append(ForceReading(s.name, self.clock(), -1, math.nan, Flags.INVALID_INPUT,
                                    detail=f"source error: {exc}; sensor dropped"))
            return None
        tf, t1 = r.tf, r.t1
        if tf is None:
            s.alive = False
            return None
        if self.options.report_stale:
            for index, ts in tf.meta.get("superseded", ()):
                out.append(ForceReading(s.name, ts, index, math.nan, Flags.STALE,
                                        detail=f"superseded by frame {tf.index}"))
        # Latency counts from when the source had the frame (its arrival stamp); a source
        # that stamps none: from when read() returned it.
        start = tf.arrival_ns if tf.arrival_ns is not None else t1
        if start > t1:  # on one clock a frame is stamped before read() returned it
            raise SourceError(f"sensor {s.name!r}: {type(s.source).__name__} stamped frame {tf.index} "
                              f"TimedFrame.arrival_ns={start}, after read() returned it at {t1} on the runtime's "
                              "clock; expected arrival stamps of the runtime's clock (time.monotonic_ns() unless "
                              "ForceRuntime was given another clock; not time.time_ns())")
        self._warm.seen(s.name, start)
        lane = self._lanes[s.name]
        lane.last = None
        return _Pending(lane, tf, start, StageLatency(source_ms=(t1 - r.t0) / 1e6), t1, _NO_FRAME)  # ns -> ms

    def _gate(self, p: _Pending) -> None:
        """The frame's own sensor's work: gate, sensor watch and, in contact, the depth stage
        (depth bundles); touches that sensor's parts only (a worker thread may run it)."""
        lane = p.lane
        t1 = self.clock() if self._warm.grabbers is not None else p.t1  # the grabber's read was earlier
        gating = lane.gating
        g = p.gate = gating.run(p.tf)  # gate
        if g is None:  # the frame contract or its exposure refused it
            return
        frame = p.frame = gating.frame
        lane.watch.observe(frame, g)  # sensor watch
        t2 = self.clock()
        lat = p.lat
        lat.gate_ms = (t2 - t1) / 1e6
        if g.mismatch or g.invalid or not g.contact:
            return
        depth = lane.sensor.depth
        if depth is not None:  # depth
            p.res = depth_of(depth, frame, g)
            lat.depth_ms = (self.clock() - t2) / 1e6

    def _settle(self, p: _Pending, out: list[ForceReading]) -> bool:
        """The reading of a gated frame that needs no model (to ``out``: False), or True: the
        frame waits for the batched predict."""
        lane, tf, g = p.lane, p.tf, p.gate
        name, lat = lane.sensor.name, p.lat
        if g is None:
            out.append(self._finish(self._judge.invalid(name, tf, lat, lane.gating.problem), p.start_ns))
            return False
        if self.tap[0] or self.tap[1]:  # copies: the gate reuses its mask, a source may reuse its frame
            frame = p.frame
            self.tapped.append((name, tf.timestamp_ns, frame.copy() if self.tap[0] else None,
                                g.mask.copy() if self.tap[1] else None))
        if g.mismatch or g.invalid or not g.contact:  # judged without the model
            out.append(self._finish(self._judge.gated(name, tf, g, lat, lane.watch.pressed, lane.sensor.gate),
                                    p.start_ns))
            return False
        if lane.shared:
            p.net = g.reduced
        res = p.res
        if res is not None:
            if not res.ok:
                out.append(self._finish(self._judge.invalid(name, tf, lat, f"depth stage failed: {res.detail}",
                                                            g.area_px), p.start_ns))
                return False
            p.depth = res.depth
        return True

    def _infer(self, pending: list[_Pending], out: list[ForceReading]) -> None:
        """One batched predict for the step's frames in contact, then each one's reading."""
        n = len(pending)
        reduced = self._net is not None and (pending[0].net is not None if n == 1
                                             else all(p.net is not None for p in pending))
        if n == 1:  # views, no copy: the model copies into its own bound input buffer
            p0 = pending[0]
            rgb = p0.net[None] if reduced and p0.net is not None else p0.frame[None]
            depth = p0.depth.reshape(1, *p0.depth.shape[:2], 1) if p0.depth is not None else None
        else:
            for k, p in enumerate(pending):
                if reduced and self._net is not None and p.net is not None:  # reduced: every net is set
                    self._net[k] = p.net
                else:
                    self._rgb[k] = p.frame
            depth = None
            if self.needs_depth:
                ds = [p.depth for p in pending if p.depth is not None]
                if len(ds) == n and all(d.size == self._depth[0].size for d in ds):
                    for k, d in enumerate(ds):
                        self._depth[k] = d.reshape(self._depth.shape[1:])
                    depth = self._depth[:n]
                elif len(ds) == n:  # depth stages on different grids (a custom depth_factory)
                    depth = np.stack([d.reshape(*d.shape[:2], 1) for d in ds])
            rgb = self._net[:n] if reduced and self._net is not None else self._rgb[:n]
        t0 = self.clock()
        error = ""
        try:
            if reduced:
                forces = self.model.predict_reduced(rgb, depth)
            else:
                forces = self.model.predict(rgb, depth)
        except Exception as exc:  # a backend failure must not stop the other readings
            forces, error = np.full(n, np.nan, np.float32), f"inference failed: {type(exc).__name__}: {exc}"
        inf_ms = (self.clock() - t0) / 1e6
        self.stats.inferred += n
        judge = self._judge
        keep = self._warm.watching  # the last input, for the next warm-up (while one may run)
        for p, raw in zip(pending, forces):
            g = p.gate
            assert g is not None  # a frame in contact
            if keep:
                p.lane.last = (p.tf, float(raw), g)
            lat = p.lat
            lat.inference_ms = inf_ms
            r = judge.estimate(p.lane.sensor.name, p.tf, float(raw), g, lat, error, p.lane.watch.foreign)
            out.append(self._finish(r, p.start_ns))
