"""The latency-bounded loop: sources -> gates -> [depth] -> one batched inference -> readings.

One :meth:`ForceRuntime.step` reads the newest frame of every live sensor, gates it, runs
the depth stage (depth bundles only) and one ``predict`` call for all sensors in contact
(batch 2 when both fingers touch), and returns one :class:`ForceReading` per frame:

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
  is dropped; the other sensor keeps being served.

Two sensors are read side by side: each sensor's ``read()`` runs in its own grabber thread,
which holds at most one frame read ahead, so one sensor never waits for the other's
camera; a step serves every sensor whose frame is there (batch 2 when both are).

Sinks that log frames or contact masks (the MCAP writer with ``frames`` / ``mask``) get each
gated frame and the gate's full-resolution mask through ``write_frame`` (:func:`frame_sinks`);
with none, no frame is copied and the full-resolution mask is not made. In paper depth mode
the zero-depth reference follows the gate's background, also when the gate re-learns it.

Latency per stage is in every reading and as rolling p50/p99 (:meth:`ForceRuntime.latency`).
Timing uses an injectable ``clock`` (ns) so tests drive it deterministically.
"""

from __future__ import annotations

import logging
import math
import threading
import time
import weakref
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, cast

import numpy as np

from ..bundle.interval import ForceInterval, usable_interval
from ..bundle.manifest import Manifest
from ..checks import check_fields, expect
from ..errors import ArgumentTypeError, FrameError, ModelClosedError, OptionsError
from ..frames import FRAME_SHAPE, FrameSource, TimedFrame, check_frame, exposure_problem
from ..gate.contact_gate import ContactGate, GateResult
from ..reading import Flags, ForceReading, StageLatency
from ..typed_json import check
from .grabbers import Grabbers as _Grabbers
from .grabbers import Read as _Read
from .grabbers import read_once as _read
from .judging import EstimateJudge, gate_verdict

if TYPE_CHECKING:  # the depth code is imported only for depth bundles
    from ..depth import DepthOptions, DepthStage

_log = logging.getLogger(__name__)

STAGES = ("source", "gate", "depth", "inference", "total")
_NO_CONTACT, _SATURATED = int(Flags.NO_CONTACT), int(Flags.SATURATED)
_STALE, _LATE, _INVALID = int(Flags.STALE), int(Flags.LATE), int(Flags.INVALID_INPUT)
_MISMATCH, _OOD = int(Flags.BACKGROUND_MISMATCH), int(Flags.OUT_OF_DISTRIBUTION)


class ForceModel(Protocol):
    """What the runtime needs from a backend (OnnxForceModel, the OAK backend)."""

    @property
    def needs_depth(self) -> bool: ...

    def predict(self, rgb: np.ndarray, depth: np.ndarray | None = None) -> np.ndarray: ...

    def close(self) -> None:
        """Release the session / device (the runtime calls it from :meth:`ForceRuntime.close`)."""


class ReadingSink(Protocol):
    def write(self, reading: ForceReading) -> None: ...

    def close(self) -> None: ...


class FrameSink(Protocol):
    """A sink that also logs frames and/or contact masks (the MCAP writer): ``frames`` /
    ``mask`` say which it wants; :meth:`ForceRuntime.run` hands them only then."""

    frames: bool
    mask: bool

    def write_frame(self, sensor: str, timestamp_ns: int, frame_bgr: np.ndarray | None,
                    mask: np.ndarray | None = None) -> None: ...


def frame_sinks(sinks: Iterable[object]) -> list[FrameSink]:
    """The sinks with a ``write_frame`` that want frames or masks (``frames`` / ``mask`` true)."""
    return [cast(FrameSink, s) for s in sinks if callable(getattr(s, "write_frame", None))
            and (getattr(s, "frames", False) or getattr(s, "mask", False))]


@dataclass
class RuntimeOptions:
    """deadline_ms: per-frame budget from frame arrival to reading (60 fps -> 16.7 ms).
    threads: ORT intra-op threads (used when the runtime loads the model).
    report_stale: emit a ``stale`` reading for every superseded frame.
    latency_window: frames kept for the rolling p50/p99.
    grabbers: read each sensor in its own grabber thread (None: when there are two sensors;
    one sensor is read in the loop's thread, the lowest-latency path).

    Raises :class:`OptionsError` naming the field when deadline_ms is not a finite number > 0,
    threads < 1 or latency_window < 1, :class:`ArgumentTypeError` for a value of another type."""

    deadline_ms: float = field(default=16.7, metadata=check(
        gt=0, expected="a finite number of milliseconds > 0 (e.g. 16.7 for 60 fps)"))
    threads: int = field(default=1, metadata=check(ge=1))
    report_stale: bool = True
    latency_window: int = field(default=600, metadata=check(ge=1))
    grabbers: bool | None = None

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass
class Sensor:
    """One tactile sensor: its frame source and its contact gate; ``depth`` is the depth
    stage the runtime built for it (None for RGB-only bundles)."""

    name: str
    source: FrameSource
    gate: ContactGate
    depth: Any = None  # edge.depth.DepthStage (process(frame, mask), set_reference(frames))
    alive: bool = True
    error: str = ""

    def __post_init__(self) -> None:
        expect(self.name, str, "Sensor.name", "a non-empty string (the sensor's name in readings)", nonempty=True)
        if not callable(getattr(self.source, "read", None)):
            raise ArgumentTypeError(f"Sensor.source={self.source!r}: expected a frame source (an object with read() "
                                    f"and close(), e.g. ReplayFolderSource(folder)), got {type(self.source).__name__}")
        expect(self.gate, ContactGate, "Sensor.gate", "a ContactGate (one per sensor)")


@dataclass
class RuntimeStats:
    """Counters over a run; latency_ms[stage] = {'p50': ms, 'p99': ms}."""

    readings: int = 0
    processed: int = 0
    inferred: int = 0
    no_contact: int = 0
    stale: int = 0
    late: int = 0
    invalid: int = 0
    source_errors: int = 0
    background_mismatch: int = 0
    out_of_distribution: int = 0
    latency_ms: dict[str, dict[str, float]] = field(default_factory=dict)

    def as_dict(self) -> dict:
        return asdict(self)


class LatencyWindow:
    """Rolling per-stage latencies (ms) in a preallocated ring buffer."""

    def __init__(self, size: int) -> None:
        self._buf = np.full((max(1, size), len(STAGES)), np.nan, np.float64)
        self._i = 0
        self._n = 0

    def add(self, lat: StageLatency) -> None:
        row = self._buf[self._i]
        row[0], row[1], row[2] = lat.source_ms, lat.gate_ms, lat.depth_ms
        row[3], row[4] = lat.inference_ms, lat.total_ms
        self._i = (self._i + 1) % len(self._buf)
        self._n = min(self._n + 1, len(self._buf))

    def percentiles(self) -> dict[str, dict[str, float]]:
        if self._n == 0:
            return {s: {"p50": math.nan, "p99": math.nan} for s in STAGES}
        p = np.percentile(self._buf[: self._n], [50, 99], axis=0)
        return {s: {"p50": float(p[0, k]), "p99": float(p[1, k])} for k, s in enumerate(STAGES)}


_USERS_LOCK = threading.Lock()
#: model -> [open runtimes using it, an owning runtime has closed]; weak keys: a runtime that was
#: never closed leaves no entry behind once its model is gone (ids would be reused).
_USERS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_USERS_BY_ID: dict[int, list] = {}  # models that cannot be weakly referenced (held alive by their runtimes)


def _entry(model: object, default: int) -> list:
    try:
        return _USERS.setdefault(model, [default, False])
    except TypeError:  # not weakly referenceable / not hashable
        return _USERS_BY_ID.setdefault(id(model), [default, False])


def _attach(model: object) -> None:
    with _USERS_LOCK:
        _entry(model, 0)[0] += 1


def _detach(model: object, owner: bool) -> bool:
    """One runtime less uses ``model``; True when the model is to be closed now: the last
    runtime has closed and one of them owned it."""
    with _USERS_LOCK:
        entry = _entry(model, 1)
        entry[0] -= 1
        entry[1] = entry[1] or owner
        if entry[0] > 0:
            return False
        try:
            _USERS.pop(model, None)
        except TypeError:
            pass
        _USERS_BY_ID.pop(id(model), None)
        return bool(entry[1])


#: Files shipped with the package (``package:FILE`` in scenes and manifests).
ASSETS_DIR = Path(__file__).resolve().parents[1] / "assets"


def _record_options(record: object) -> dict[str, Any]:
    """The DepthOptions values a depth record sets (None = not set): its fields by name;
    a manifest's ``reduction`` (a FrameReduction, factor k > 1: depth made at the network
    resolution) becomes DepthOptions ``downscale`` = k and ``reduction`` = its method."""
    import dataclasses

    out: dict[str, Any] = {}
    for f in dataclasses.fields(record):  # type: ignore[arg-type]
        value = getattr(record, f.name)
        if value is None:
            continue
        if f.name == "reduction" and hasattr(value, "factor"):
            if value.factor > 1:  # depth at the network resolution (the grid the model reads)
                out["downscale"] = value.factor
                out["reduction"] = value.method.value
            continue
        out[f.name] = value
    return out


def depth_options_for(settings: object | None = None, manifest: Manifest | None = None) -> DepthOptions:
    """The depth stage's typed options for a depth bundle, merged in this one place: each
    :class:`~tactile_force.edge.depth.DepthOptions` field from the scene's ``[depth]`` table
    (``settings``: a :class:`~tactile_force.edge.scene.DepthSettings`, or any dataclass with
    DepthOptions field names, e.g. a DepthOptions), else from what the bundle's manifest
    recorded at training time (``manifest.depth``, a
    :class:`~tactile_force.edge.bundle.manifest.DepthRecord`), else the DepthOptions default.

    Generic over the fields (``dataclasses.fields``): a field a record shares by name with
    DepthOptions flows through without an edit here; None means "not set"; record fields
    DepthOptions does not have (``mapping_sha256``, ``mask``) are not options. A mapping
    named ``package:FILE`` is a file shipped in tactile_force/edge/assets (e.g. the virtual
    DIGIT's calibration that the reference depth models were trained with).

    Raises
    ------
    SceneError
        No mapping anywhere (``depth.mapping``), or a value DepthOptions refuses (``depth``).
    """
    import dataclasses

    from ..depth import DepthOptions  # noqa: PLC0415 - lazy on purpose
    from ..errors import SceneError

    names = {f.name for f in dataclasses.fields(DepthOptions)}
    values: dict[str, Any] = {}
    for record in (manifest.depth if manifest is not None else None, settings):  # the scene's table wins
        if record is not None:
            values.update({k: v for k, v in _record_options(record).items() if k in names})
    if "mapping" not in values:
        raise SceneError("depth.mapping: missing; a depth bundle needs the colour->normal .npz "
                         "(the paper MLP or a 'tactile-force calibrate-depth' result) in the scene's [depth] "
                         "table or the bundle manifest")
    values["mapping"] = resolve_package_path(str(values["mapping"]))
    try:
        return DepthOptions(**values)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"depth: {exc}") from None


def resolve_package_path(path: str) -> str:
    """``package:FILE`` -> the file shipped in tactile_force/edge/assets; other paths unchanged."""
    if path.startswith("package:"):
        return str(ASSETS_DIR / path.split(":", 1)[1])
    return path


def build_depth_stage(settings: object | None = None, manifest: Manifest | None = None) -> DepthStage:
    """The depth stage for D/Dmod/RGBmod+D bundles (imported only for those); settings and
    manifest as in :func:`depth_options_for`."""
    from ..depth import DepthStage  # noqa: PLC0415 - lazy on purpose
    from ..errors import SceneError

    options = depth_options_for(settings, manifest)
    try:
        return DepthStage(options)
    except (TypeError, ValueError) as exc:  # MappingError: the mapping file is unusable
        raise SceneError(f"depth: {exc}") from None


def plan_stages(sensors: Iterable[str], needs_depth: bool, backend: str = "cpu") -> list[str]:
    """Names of the stages a runtime will run, in order, e.g. ['source:left', 'gate:left',
    'inference:cpu']; 'depth:NAME' only for depth bundles."""
    out = []
    for name in sensors:
        out += [f"source:{name}", f"gate:{name}"] + ([f"depth:{name}"] if needs_depth else [])
    return out + [f"inference:{backend}"]


@dataclass(slots=True)
class _Pending:
    sensor: Sensor
    tf: TimedFrame
    frame: np.ndarray
    gate: GateResult
    start_ns: int
    source_ms: float
    gate_ms: float
    depth_ms: float = 0.0
    depth: np.ndarray | None = None
    net: np.ndarray | None = None  # the gate's reduced image when the model reads it as it is


def shares_reduction(gate: ContactGate, model: object) -> bool:
    """True when ``model`` reads images reduced exactly as ``gate`` reduces frames (its
    ``reduction`` equals the gate's, not ``none``) and takes them through ``predict_reduced``:
    then the runtime hands it the gate's image and each frame is downscaled once."""
    red = getattr(model, "reduction", None)
    return (callable(getattr(model, "predict_reduced", None)) and getattr(model, "rgb_shape", None) is not None
            and red is not None and red.factor > 1 and red == gate.reduction)


def _check_runtime_args(sensors: object, model: object, options: object, clock: object, depth_factory: object,
                        backend: object, owns_model: object) -> None:
    """The arguments of :class:`ForceRuntime`, checked once; ArgumentTypeError / OptionsError
    naming the parameter."""
    if isinstance(sensors, Sensor):
        raise ArgumentTypeError("ForceRuntime.sensors: got one Sensor; expected a list of 1 or 2 Sensor "
                                "(one per finger): pass [sensor]")
    expect(sensors, (list, tuple), "ForceRuntime.sensors", "a list of 1 or 2 Sensor (one per finger)")
    assert isinstance(sensors, (list, tuple))
    if not 1 <= len(sensors) <= 2:
        raise OptionsError(f"ForceRuntime.sensors: {len(sensors)} sensors; expected 1 or 2 (one per finger)")
    for i, s in enumerate(sensors):
        expect(s, Sensor, f"ForceRuntime.sensors[{i}]", "a Sensor(name, source, gate)")
    if not callable(getattr(model, "predict", None)):
        raise ArgumentTypeError(f"ForceRuntime.model={model!r}: expected a force model with predict() "
                                f"(e.g. OnnxForceModel(bundle)), got {type(model).__name__}")
    expect(options, (RuntimeOptions, type(None)), "ForceRuntime.options", "a RuntimeOptions or None (the defaults)")
    expect(clock, Callable, "ForceRuntime.clock", "a callable returning monotonic ns (e.g. time.monotonic_ns)")
    expect(depth_factory, (Callable, type(None)), "ForceRuntime.depth_factory", "a callable making a depth stage, "
                                                                                 "or None (the default)")
    expect(backend, str, "ForceRuntime.backend", "a backend name such as 'cpu'", nonempty=True)
    expect(owns_model, bool, "ForceRuntime.owns_model")


class ForceRuntime:
    """Serve force readings for one or two sensors from one model.

    sensors: one or two :class:`Sensor` (names unique). model: an object with
    ``predict(rgb, depth=None)`` and ``needs_depth`` (OnnxForceModel, the OAK backend); a
    closed model is refused (:class:`ModelClosedError`). One model may be shared by several
    runtimes and threads (OnnxForceModel serialises its calls). depth_factory: builds one
    depth stage per sensor for depth models (default :func:`build_depth_stage`). clock:
    monotonic ns; give sources the same clock.

    owns_model: whether :meth:`close` closes the model. True (default, what callers that
    load a model for this runtime want): the model is closed, but only once the last runtime
    using it has closed, so closing one of two runtimes sharing a model never breaks the
    other. False: this runtime never asks for the model to be closed (a model you keep using
    and close yourself; it is still closed when an owning runtime sharing it closes last).
    """

    def __init__(self, sensors: list[Sensor], model: ForceModel, options: RuntimeOptions | None = None,
                 clock: Callable[[], int] = time.monotonic_ns,
                 depth_factory: Callable[[], object] | None = None, backend: str = "cpu",
                 owns_model: bool = True) -> None:
        _check_runtime_args(sensors, model, options, clock, depth_factory, backend, owns_model)
        if getattr(model, "closed", False):
            bundle = getattr(model, "bundle", None)
            raise ModelClosedError(f"{getattr(bundle, 'path', 'model')}: ForceRuntime was given a closed model; "
                                   "load the bundle again")
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
        nd = getattr(model, "needs_depth", None)
        if nd is None:  # backends that only carry the bundle (OAK)
            nd = getattr(model, "bundle").manifest.needs_depth  # noqa: B009 - not in the ForceModel protocol
        self.needs_depth = bool(nd)
        if self.needs_depth:
            bundle = getattr(model, "bundle", None)
            manifest = bundle.manifest if bundle is not None else None
            factory = depth_factory or (lambda: build_depth_stage(None, manifest))
            for s in sensors:
                s.depth = factory()
        self.stages = plan_stages(names, self.needs_depth, backend)
        self.stats = RuntimeStats()
        self._window = LatencyWindow(self.options.latency_window)
        self._rgb = np.empty((len(sensors), *FRAME_SHAPE), np.uint8)
        self._depth = np.empty((len(sensors), FRAME_SHAPE[0], FRAME_SHAPE[1], 1), np.uint8)
        # One downscale per frame: a sensor whose gate reduces frames the way the model's
        # network input is reduced hands the gate's reduced image to ``predict_reduced``.
        self._shared = {s.name: shares_reduction(s.gate, model) for s in sensors}
        net_shape = getattr(model, "rgb_shape", None)
        self._net = (np.empty((len(sensors), *net_shape), np.uint8)
                     if any(self._shared.values()) and net_shape is not None else None)
        use = self.options.grabbers
        self._use_grabbers = len(sensors) > 1 if use is None else bool(use)
        self._grabbers: _Grabbers | None = None
        self._reference_frames: dict[str, list[np.ndarray]] = {}  # paper depth mode, while learning
        self._relearned: dict[str, int] = {s.name: s.gate.relearned for s in sensors}  # paper mode
        #: (frames, masks) to keep for frame sinks; (False, False) = none kept (zero cost).
        self.tap: tuple[bool, bool] = (False, False)
        #: (sensor, timestamp ns, HxWx3 uint8 BGR copy or None, HxW uint8 0/255 mask copy or
        #: None) of the frames gated in the last step, when :attr:`tap` asks for them.
        self.tapped: list[tuple[str, int, np.ndarray | None, np.ndarray | None]] = []
        #: the sensor the model's force calibration was fitted on (None: not calibrated, or no record)
        self._fingerprint = getattr(getattr(model, "calibration", None), "sensor", None)
        self._sensor_checks = self._fingerprint is not None
        self._bg_seen: dict[str, tuple[bool, int]] = {}  # per sensor: (background ready, re-learnt count) checked
        self._foreign: dict[str, str] = {}  # per sensor: why it is not the calibration's sensor ("" = it is)
        from ..gate.given_background import reference_thumb

        self._ref_thumb, self._ref_what, self._ref_min = reference_thumb(model)
        self._bg_checked: dict[str, np.ndarray] = {}  # per sensor: the given background image checked
        self._pressed: dict[str, str] = {}  # per sensor: why its given background looks pressed ("" = it does not)
        self._judging = EstimateJudge(model)  # range, saturation, out_of_distribution (edge/runtime/judging.py)
        self._interval = usable_interval(getattr(model, "bundle", None))  # every reading's error bar
        _attach(model)  # last: a runtime that failed to build does not count as a user

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
        if self._use_grabbers:
            reads = self._start().take(live)
        else:
            reads = [(s, _read(s.source, self.clock)) for s in live]
        for s, rd in reads:
            p = self._acquire(s, rd, out)
            if p is not None:
                pending.append(p)
        if pending:
            self._infer(pending, out)
        for r in out:
            self._count(r)
        return out

    def start(self, wait_s: float = 0.0) -> bool:
        """Start the grabber threads (step() does on its first call) and wait up to ``wait_s``
        seconds until every live sensor has a frame read, so the first step serves them all
        in one batch. True when they have (always True without grabber threads)."""
        self._check_open()
        if not self._use_grabbers:
            return True
        return self._start().wait_all([s for s in self.sensors if s.alive], wait_s)

    def _start(self) -> _Grabbers:
        if self._grabbers is None:
            self._grabbers = _Grabbers(self.sensors, self.clock)
        return self._grabbers

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
        """Stop the grabber threads, close every source, then the model when this runtime
        owns it and no other runtime still uses it (see ``owns_model``). Idempotent."""
        if self._closed:
            return
        self._closed = True
        if self._grabbers is not None:
            self._grabbers.stop(timeout_s=0.0)
        for s in self.sensors:
            s.source.close()
        if self._grabbers is not None:
            self._grabbers.stop()
            self._grabbers = None
        close_model = getattr(self.model, "close", None)
        if _detach(self.model, self.owns_model) and close_model is not None:
            close_model()

    # -- internals ------------------------------------------------------------------------
    def _ms(self, a: int, b: int) -> float:
        return (b - a) / 1e6

    def _reading(self, s: Sensor, tf: TimedFrame | None, flags: Flags, force: float = math.nan,
                 latency: StageLatency | None = None, detail: str = "", area: int = 0,
                 raw: float = math.nan, settled: bool = True) -> ForceReading:
        """A reading; its error bar comes from the bundle's interval only when it has a force
        and ``settled``: the gate judged the frame against a settled background (False while
        the background is learnt: nothing is known then, the interval stays ``unknown``)."""
        r = ForceReading(
            sensor=s.name,
            timestamp_ns=tf.timestamp_ns if tf is not None else self.clock(),
            frame_index=tf.index if tf is not None else -1,
            force_n=force, flags=flags, latency=latency or StageLatency(), raw_force_n=raw,
            contact_area_px=area, truth_n=tf.truth_n if tf is not None else None, detail=detail,
        )
        if force == force and settled:  # an estimate (0 N for no_contact) judged: its error bar
            self._bound(r)
        return r

    def _finish(self, r: ForceReading, start_ns: int) -> ForceReading:
        r.latency.total_ms = self._ms(start_ns, self.clock())
        if r.latency.total_ms > self.options.deadline_ms:
            r.flags |= Flags.LATE
        self._window.add(r.latency)
        return r

    def _acquire(self, s: Sensor, r: _Read, out: list[ForceReading]) -> _Pending | None:
        if r.error is not None:
            exc = r.error
            s.alive, s.error = False, str(exc)
            self.stats.source_errors += 1
            out.append(self._reading(s, None, Flags.INVALID_INPUT, detail=f"source error: {exc}; sensor dropped"))
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
        lat = StageLatency(source_ms=self._ms(r.t0, t1))
        if self._grabbers is not None:
            t1 = self.clock()  # the gate's time starts here (the grabber's read was earlier)
        try:
            frame = check_frame(tf.frame, name=f"{s.name} frame {tf.index}", shape=FRAME_SHAPE)
        except FrameError as exc:
            out.append(self._finish(self._reading(s, tf, Flags.INVALID_INPUT, latency=lat, detail=str(exc)), start))
            return None
        # The frame's one downscale happens here when the gate works reduced: exposure is judged
        # on that image (box averages keep the mean), the gate and the model then read it too.
        problem = exposure_problem(s.gate.reduce(frame) if s.gate.reduction.factor > 1 else frame)
        if problem:
            out.append(self._finish(self._reading(s, tf, Flags.INVALID_INPUT, latency=lat,
                                                  detail=f"{s.name} frame {tf.index}: {problem} "
                                                         "(LEDs off, lens covered?)"), start))
            return None
        g = s.gate.update(frame)
        if s.gate.background_image is not None and self._bg_checked.get(s.name) is not s.gate.background_image:
            self._check_background(s)  # once per background given to the gate
        if self._sensor_checks:  # once per new background: is this the sensor the bundle was calibrated on?
            self._check_sensor(s, frame, g)
        if s.depth is not None and (getattr(s.depth, "needs_reference", False)
                                    or s.gate.relearned != self._relearned[s.name]):
            self._depth_reference(s, frame, g)
        if self.tap[0] or self.tap[1]:  # copies: the gate reuses its mask, a source may reuse its frame
            self.tapped.append((s.name, tf.timestamp_ns, frame.copy() if self.tap[0] else None,
                                g.mask.copy() if self.tap[1] else None))
        t2 = self.clock()
        lat.gate_ms = self._ms(t1, t2)
        if g.mismatch or g.invalid:  # the gate cannot judge this frame: no force (see _gate_verdict)
            out.append(self._finish(self._gate_verdict(s, tf, g, lat), start))
            return None
        if not g.contact:
            detail = "" if g.background_ready else "learning background"
            if self._pressed.get(s.name):  # the given background holds a press: "no contact" is not known
                out.append(self._finish(self._reading(s, tf, Flags.NO_CONTACT | Flags.BACKGROUND_MISMATCH,
                                                      latency=lat, detail=self._pressed[s.name], area=g.area_px),
                                        start))
                return None
            out.append(self._finish(self._reading(s, tf, Flags.NO_CONTACT, 0.0, lat, detail, g.area_px,
                                                  settled=g.background_ready), start))
            return None
        p = _Pending(s, tf, frame, g, start, lat.source_ms, lat.gate_ms)
        if self._shared[s.name]:
            p.net = g.reduced
        if s.depth is not None:
            # a depth stage at the network resolution reads the gate's reduced image and mask
            # (the frame's one downscale); otherwise the frame and the full-resolution mask
            grid = getattr(s.depth, "grid_frame_shape", None)
            if grid is not None and g.reduced is not None and g.reduced.shape == grid:
                res = s.depth.process(g.reduced, g.reduced_mask, checked=True)  # exposure judged above
            else:
                res = s.depth.process(frame, g.mask)
            t3 = self.clock()
            p.depth_ms = self._ms(t2, t3)
            if not getattr(res, "ok", False):
                lat.depth_ms = p.depth_ms
                out.append(self._finish(self._reading(s, tf, Flags.INVALID_INPUT, latency=lat, area=g.area_px,
                                                      detail=f"depth stage failed: {getattr(res, 'detail', '')}"),
                                         start))
                return None
            p.depth = res.depth
        return p

    def check_backgrounds(self) -> dict[str, str]:
        """Check every sensor's given background (``ContactGate.capture_background``) for a
        press now (the runtime also does on the first frame after one is given): sensor ->
        why it looks pressed, or "" (fine, or no reference in the bundle to check it against;
        edge/gate/given_background.py). While it looks pressed, the sensor's ``no_contact``
        readings carry ``background_mismatch`` and no force."""
        for s in self.sensors:
            if s.gate.background_image is not None and self._bg_checked.get(s.name) is not s.gate.background_image:
                self._check_background(s)
        return {s.name: self._pressed.get(s.name, "") for s in self.sensors}

    def _check_background(self, s: Sensor) -> None:
        from ..gate.given_background import pressed_background

        img = s.gate.background_image
        assert img is not None
        self._bg_checked[s.name] = img
        origin = f"sensor {s.name}: the background given ({s.gate.background_origin or 'capture_background'})"
        if self._ref_thumb is None:
            self._pressed[s.name] = ""
            if not getattr(self, "_unchecked_said", False):
                self._unchecked_said = True
                _log.info("%s cannot be checked for a press: the bundle carries no no-contact image of the sensor "
                          "(calibrate-force --background, or export/quantize/compress --background, record one)",
                          origin)
            return
        why = pressed_background(img, self._ref_thumb, self._ref_what, origin, min_cells=self._ref_min)
        self._pressed[s.name] = why
        if why:
            _log.warning("%s; its no_contact readings are flagged background_mismatch (no force)", why)

    def _check_sensor(self, s: Sensor, frame: np.ndarray, g: GateResult) -> None:
        """Compare the sensor with the one the force calibration was fitted on, once per new
        background (learnt, given or re-learnt), on the first no-contact frame that fits it:
        its serial when the source knows one, else the calibration's no-contact fingerprint
        (:func:`~.force_calibration.fingerprint_mismatch`). A mismatch flags every contact
        reading of the sensor ``out_of_distribution``, the detail naming it."""
        state = (s.gate.background_ready, s.gate.relearned)
        if state == self._bg_seen.get(s.name):
            return
        assert self._fingerprint is not None
        attached = getattr(s.source, "attached", None)
        serial = str(getattr(s.source, "serial", "") or getattr(attached, "serial", "") or "")
        known = bool(serial and self._fingerprint.serial)  # two serials decide at once
        if s.gate.background_ready and not known and (g.contact or g.mismatch or g.invalid
                                                      or self._pressed.get(s.name)):
            return  # wait for a no-contact frame that fits a background without a press
        self._bg_seen[s.name] = state
        if not s.gate.background_ready:
            return
        from ..bundle.force_calibration import fingerprint_mismatch

        why = fingerprint_mismatch(self._fingerprint, frame, serial)
        if why and why != self._foreign.get(s.name):
            _log.warning("sensor %s: %s; its contact readings are flagged out_of_distribution", s.name, why)
        self._foreign[s.name] = f"sensor {s.name}: {why}" if why else ""

    def _depth_reference(self, s: Sensor, frame: np.ndarray, g: GateResult) -> None:
        """Paper depth mode: the zero-depth reference is the gate's background. The frames the
        gate learns it from are kept and handed to the depth stage once it is learnt; when the
        gate re-learns its background after a mismatch (from this frame), the reference is
        re-set from it too, so depth stays zero where the gel is untouched."""
        if s.gate.relearned != self._relearned[s.name]:
            self._relearned[s.name] = s.gate.relearned
            if getattr(getattr(s.depth, "options", None), "mode", "") == "paper":
                try:
                    s.depth.set_reference([frame])
                except ValueError as exc:  # unusable frame: keep the reference it had
                    _log.warning("sensor %s: paper depth reference not re-set after the gate re-learnt its "
                                 "background (%s); keeping the previous one", s.name, exc)
            return
        keep = self._reference_frames.setdefault(s.name, [])
        if not g.background_ready:
            keep.append(frame.copy())
        if s.gate.background_ready and keep:
            s.depth.set_reference(keep)
            keep.clear()

    def _infer(self, pending: list[_Pending], out: list[ForceReading]) -> None:
        n = len(pending)
        reduced = self._net is not None and (pending[0].net is not None if n == 1
                                             else all(p.net is not None for p in pending))
        if n == 1:  # views, no copy: the model copies into its own bound input buffer
            p0 = pending[0]
            rgb = p0.net[None] if reduced and p0.net is not None else p0.frame[None]
            depth = p0.depth.reshape(1, *p0.depth.shape[:2], 1) if p0.depth is not None else None
        else:
            for k, p in enumerate(pending):
                if reduced and self._net is not None:
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
                elif len(ds) == n:  # depth images at another size (the network resolution)
                    depth = np.stack([d.reshape(*d.shape[:2], 1) for d in ds])
            rgb = self._net[:n] if reduced and self._net is not None else self._rgb[:n]
        t0 = self.clock()
        error = ""
        try:
            if reduced:
                forces = self.model.predict_reduced(rgb, depth)  # type: ignore[attr-defined]
            else:
                forces = self.model.predict(rgb, depth)
        except Exception as exc:  # a backend failure must not stop the other readings
            forces, error = np.full(n, np.nan, np.float32), f"inference failed: {type(exc).__name__}: {exc}"
        inf_ms = self._ms(t0, self.clock())
        self.stats.inferred += n
        for p, raw in zip(pending, forces):
            lat = StageLatency(p.source_ms, p.gate_ms, p.depth_ms, inf_ms)
            foreign = self._foreign.get(p.sensor.name, "") if self._foreign else ""
            flags, force, detail = self._judging.estimate(float(raw), p.gate, error, foreign)
            r = self._reading(p.sensor, p.tf, flags, force, lat, detail, p.gate.area_px, float(raw),
                              p.gate.background_ready)
            out.append(self._finish(r, p.start_ns))

    def _gate_verdict(self, s: Sensor, tf: TimedFrame, g: GateResult, lat: StageLatency) -> ForceReading:
        """The reading for a frame the gate cannot judge (force NaN, the CNN not run; edge/runtime/judging.py)."""
        flags, detail = gate_verdict(s.name, tf.index, g, s.gate.options.relearn_frames)
        return self._reading(s, tf, flags, latency=lat, area=g.area_px, detail=detail)

    @property
    def interval(self) -> ForceInterval | None:
        """The bundle's interval record applied to every reading (None: every reading's
        interval is ``unknown``: the manifest has none, or it was fitted for another model)."""
        return self._interval

    def _bound(self, r: ForceReading) -> None:
        """Set the reading's force_low_n / force_high_n / interval from the bundle's table:
        no_contact -> [0, the gate-closed bound]; saturated -> open above (+inf); an unknown
        bin or no table -> NaN bounds, ``unknown``. Called only for a reading with a force
        whose frame the gate judged against a settled background (:meth:`_reading`)."""
        iv = self._interval
        if iv is None:
            return
        fl = int(r.flags)  # plain int tests: IntFlag operators cost ~1 us each
        if fl & _NO_CONTACT:
            r.force_low_n, r.force_high_n, r.interval = iv.no_contact_bounds()
        else:
            r.force_low_n, r.force_high_n, r.interval = iv.bounds(r.force_n, fl & _SATURATED != 0)

    def _count(self, r: ForceReading) -> None:
        st = self.stats
        st.readings += 1
        f = int(r.flags)  # plain int tests: IntFlag's `in` costs about a microsecond each
        if f & _STALE:
            st.stale += 1
            return
        st.processed += 1
        if not f:
            return
        if f & _NO_CONTACT:
            st.no_contact += 1
        if f & _LATE:
            st.late += 1
        if f & _INVALID:
            st.invalid += 1
        if f & _MISMATCH:
            st.background_mismatch += 1
        if f & _OOD:
            st.out_of_distribution += 1
