"""What a :class:`~tactile_force.edge.runtime.loop.ForceRuntime` is built from and reports:
its options, its sensors, the :class:`ForceModel` protocol a backend satisfies, the sinks it
writes to, its counters and rolling latency window, and the check of its arguments (made
once, at construction)."""

from __future__ import annotations

import abc
import math
from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field
from typing import TYPE_CHECKING, Literal, Protocol, cast

import numpy as np

from ..bundle.manifest import FrameReduction
from ..checks import check_fields, expect, expect_members
from ..errors import ArgumentTypeError, OptionsError
from ..frames import MAX_BATCH, FrameReader, FrameSource
from ..gate.contact_gate import ContactGate
from ..limits import DEADLINE_MS, THREADS, WINDOW, as_metadata
from ..reading import Flags, ForceReading, StageLatency
from ..typed_json import check

if TYPE_CHECKING:  # the depth code is imported only for depth bundles
    from ..bundle.force_calibration import ForceCalibration
    from ..bundle.store import Bundle
    from ..depth import DepthStage

#: The stages every reading's latency names, in order.
STAGES = ("source", "gate", "depth", "inference", "total")


class ForceModel(Protocol):
    """What the runtime needs from a backend (:class:`~tactile_force.edge.model.onnx_model.OnnxForceModel`,
    the OAK backend). :class:`ForceRuntime` refuses a model that lacks one of these members
    (:class:`~tactile_force.edge.errors.ArgumentTypeError` naming it).

    Attributes
    ----------
    bundle : Bundle or None
        The bundle the model runs: its manifest gives the depth record, the data statistics
        readings are judged against, the interval and the no-contact reference (None: a model
        without a bundle; no depth record, no statistics, every interval ``unknown``).
    calibration : ForceCalibration or None
        The force calibration applied to the model's output; its ``sensor`` fingerprint is
        what the runtime compares each sensor with (None: no calibration applied).
    reduction : FrameReduction
        How :meth:`predict_reduced` expects frames reduced (``FrameReduction()``, method
        ``none``: the model reads full frames only).
    rgb_shape : tuple of int or None
        (rows, cols, 3) of the RGB images :meth:`predict_reduced` reads; None for a model
        without an RGB input.
    needs_depth : bool
        The model reads depth images (the runtime builds one depth stage per sensor).
    closed : bool
        True after :meth:`close` (a closed model is refused).
    """

    calibration: ForceCalibration | None

    @property
    def bundle(self) -> Bundle | None: ...

    @property
    def reduction(self) -> FrameReduction: ...

    @property
    def rgb_shape(self) -> tuple[int, int, int] | None: ...

    @property
    def needs_depth(self) -> bool: ...

    @property
    def closed(self) -> bool: ...

    def predict(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """Forces in N, (N,) float32, for full-resolution frames (N, 320, 240, 3) uint8 BGR and,
        for depth models, depth images (N, rows, cols, 1) uint8; N is 1 to
        :data:`~tactile_force.edge.frames.MAX_BATCH` (one frame per sensor of the runtime)."""
        ...

    def predict_reduced(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """As :meth:`predict`, for images already reduced by :attr:`reduction` (the runtime
        hands it the contact gate's reduced image, so each frame is downscaled once)."""
        ...

    def close(self) -> None:
        """Release the session / device (the runtime calls it from :meth:`ForceRuntime.close`)."""
        ...


class ForceModelBase(abc.ABC):
    """The :class:`ForceModel` members a simple backend does not need to write: it carries no
    bundle, applies no force calibration, reads full frames (``reduction`` none, so
    :meth:`predict_reduced` is :meth:`predict`) and holds nothing to release. A subclass
    writes ``predict`` and ``needs_depth`` (and overrides ``close`` / ``closed`` together
    when it holds a session or a device).

    Examples
    --------
    >>> class Constant(ForceModelBase):
    ...     needs_depth = False
    ...     def predict(self, rgb, depth=None):
    ...         return np.full(len(rgb), 5.0, np.float32)
    """

    bundle: Bundle | None = None
    calibration: ForceCalibration | None = None
    reduction: FrameReduction = FrameReduction()
    rgb_shape: tuple[int, int, int] | None = None
    closed: bool = False

    @abc.abstractmethod
    def predict(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """Forces in N, (N,) float32 (see :meth:`ForceModel.predict`); a subclass writes it."""

    def predict_reduced(self, rgb: np.ndarray | None, depth: np.ndarray | None = None) -> np.ndarray:
        """:meth:`predict`: with ``reduction`` none the reduced images are the frames."""
        return self.predict(rgb, depth)

    def prewarm(self, n: int = 1) -> None:
        """Nothing to warm (a backend whose calls run cold after a rest may override it: one
        throw-away call on its last batch-``n`` input, changing no answer)."""
        return None

    def close(self) -> None:
        """Nothing to release (a subclass holding a session or a device overrides it and ``closed``)."""
        return None


class ReadingSink(Protocol):
    """Where readings go (CSV, JSONL, stdout, MCAP, ROS 2 writers)."""

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
    grabbers: read each sensor in its own grabber thread (None: when there are two or more
    sensors; one sensor is read in the loop's thread, the lowest-latency path, except while
    warm-ups run: their rest is taken on a grabber thread, which a frame ends).
    workers: threads that run a step's per-sensor work (contact gate, sensor watch, depth
    stage) when two or more sensors' frames are ready together, the loop's own thread
    included (edge/runtime/workers.py); the batched predict and the readings stay in the
    loop's thread. None (auto): 2 when there are several sensors, two or more cores and the
    real clock (``time.monotonic_ns``), else 1 (one sensor always runs in one thread).
    prewarm: warm-ups at a slow cadence (frames 4 ms or more apart, e.g. a 60 fps sensor):
    wake shortly before the next frame is due and run its gate and model once on the last
    frame, results thrown away, so the frame finds caches warm (edge/runtime/prewarm.py); a
    frame that arrives meanwhile ends the rest or the warm-up at once. ``'auto'`` (default):
    the runtime tries them with and without on this host and keeps them only where they pay
    (edge/runtime/prewarm_decision.py; ``RuntimeStats.prewarm`` says what it found); True:
    always; False: never. Only with the runtime's real clock (``time.monotonic_ns``) and
    grabber threads (``grabbers=False`` turns them off: nothing could end the rest).

    Raises :class:`OptionsError` naming the field when deadline_ms is not a finite number > 0,
    threads < 1, latency_window < 1 or workers not 1 to 16, :class:`ArgumentTypeError` for a value of another type."""

    deadline_ms: float = field(default=16.7, metadata=check(
        gt=DEADLINE_MS.gt, le=DEADLINE_MS.le, expected="a number of milliseconds in (0, 1e9] (e.g. 16.7 for 60 fps)"))
    threads: int = field(default=1, metadata=as_metadata(THREADS))
    report_stale: bool = True
    latency_window: int = field(default=600, metadata=as_metadata(WINDOW))
    grabbers: bool | None = None
    prewarm: Literal["auto", True, False] = "auto"
    workers: int | None = field(default=None, metadata=check(
        ge=1, le=MAX_BATCH, expected=f"None (auto) or 1 to {MAX_BATCH} threads (one per sensor at most is used)"))

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass
class Sensor:
    """One tactile sensor: its frame source and its contact gate; ``depth`` is the depth
    stage the runtime built for it (None for RGB-only bundles)."""

    name: str
    source: FrameSource
    gate: ContactGate
    depth: DepthStage | None = None
    alive: bool = True
    error: str = ""

    def __post_init__(self) -> None:
        expect(self.name, str, "Sensor.name", "a non-empty string (the sensor's name in readings)", nonempty=True)
        check_source(self.source, "Sensor.source")
        expect(self.gate, ContactGate, "Sensor.gate", "a ContactGate (one per sensor)")


def check_source(source: object, name: str) -> None:
    """Refuse a frame source lacking a :class:`~tactile_force.edge.frames.FrameReader` member
    (``read``, ``close``): :class:`ArgumentTypeError` naming ``name`` and every missing member."""
    expect_members(source, FrameReader, name, "a frame source with read() and close() (e.g. "
                   "ReplayFolderSource(folder); a source of your own can subclass FrameSource)")


_NO_CONTACT = int(Flags.NO_CONTACT)
_STALE, _LATE, _INVALID = int(Flags.STALE), int(Flags.LATE), int(Flags.INVALID_INPUT)
_MISMATCH, _OOD = int(Flags.BACKGROUND_MISMATCH), int(Flags.OUT_OF_DISTRIBUTION)


@dataclass
class RuntimeStats:
    """Counters over a run; latency_ms[stage] = {'p50': ms, 'p99': ms}. ``prewarms``: warm-ups
    run before a frame was due (``RuntimeOptions.prewarm``); ``prewarm_abandoned``: warm-ups
    given up for a frame that arrived; ``prewarm_overran``: frames that arrived while one still
    ran (each waited at most for the part under way); ``prewarm``: whether warm-ups run and
    why: ``'trying'`` (the runtime is measuring whether they pay), ``'on (...)'`` or
    ``'off (...)'``."""

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
    prewarms: int = 0
    prewarm_abandoned: int = 0
    prewarm_overran: int = 0
    prewarm: str = ""
    latency_ms: dict[str, dict[str, float]] = field(default_factory=dict)

    def as_dict(self) -> dict:
        return asdict(self)

    def count(self, r: ForceReading) -> None:
        """Count one reading by its flags."""
        self.readings += 1
        f = int(r.flags)  # plain int tests: IntFlag's `in` costs about a microsecond each
        if f & _STALE:
            self.stale += 1
            return
        self.processed += 1
        if not f:
            return
        if f & _NO_CONTACT:
            self.no_contact += 1
        if f & _LATE:
            self.late += 1
        if f & _INVALID:
            self.invalid += 1
        if f & _MISMATCH:
            self.background_mismatch += 1
        if f & _OOD:
            self.out_of_distribution += 1


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


def shares_reduction(gate: ContactGate, model: ForceModel) -> bool:
    """True when ``model`` reads images reduced exactly as ``gate`` reduces frames (its
    ``reduction`` equals the gate's, not ``none``) and has an RGB input: then the runtime
    hands the gate's image to ``predict_reduced`` and each frame is downscaled once."""
    red = model.reduction
    return model.rgb_shape is not None and red.factor > 1 and red == gate.reduction


def check_runtime_args(sensors: object, model: object, options: object, clock: object, depth_factory: object,
                       backend: object, owns_model: object) -> None:
    """The arguments of :class:`ForceRuntime`, checked once.

    Raises
    ------
    ArgumentTypeError
        A wrong type, or a model that lacks a :class:`ForceModel` member (the message names
        every missing member).
    OptionsError
        Not 1 to :data:`~tactile_force.edge.frames.MAX_BATCH` (16) sensors.
    """
    want = f"a list of 1 to {MAX_BATCH} Sensor (one per fingertip or pad)"
    if isinstance(sensors, Sensor):
        raise ArgumentTypeError(f"ForceRuntime.sensors: got one Sensor; expected {want}: pass [sensor]")
    expect(sensors, (list, tuple), "ForceRuntime.sensors", want)
    assert isinstance(sensors, (list, tuple))
    if not 1 <= len(sensors) <= MAX_BATCH:
        why = ("" if not sensors else f": every frame needs its own contact-gate pass (about 0.4 to 1 ms on one "
               f"core), so {MAX_BATCH} sensors at 60 fps fill one core's 16.7 ms frame period; serve more with a "
               "second ForceRuntime")
        raise OptionsError(f"ForceRuntime.sensors: {len(sensors)} sensors; expected 1 to {MAX_BATCH}{why}")
    for i, s in enumerate(sensors):
        expect(s, Sensor, f"ForceRuntime.sensors[{i}]", "a Sensor(name, source, gate)")
        check_source(s.source, f"ForceRuntime.sensors[{i}].source")  # replaced since the Sensor was made?
    expect_members(model, ForceModel, "ForceRuntime.model",
                   "a force model with predict() and the other ForceModel members (e.g. OnnxForceModel(bundle); "
                   "a backend of your own can subclass ForceModelBase for the members it does not need)")
    expect(options, (RuntimeOptions, type(None)), "ForceRuntime.options", "a RuntimeOptions or None (the defaults)")
    expect(clock, Callable, "ForceRuntime.clock", "a callable returning monotonic ns (e.g. time.monotonic_ns)")
    expect(depth_factory, (Callable, type(None)), "ForceRuntime.depth_factory", "a callable making a depth stage, "
                                                                                 "or None (the default)")
    expect(backend, str, "ForceRuntime.backend", "a backend name such as 'cpu'", nonempty=True)
    expect(owns_model, bool, "ForceRuntime.owns_model")
