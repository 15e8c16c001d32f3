# cyclonedds.idl.types.sequence[...] is a runtime type constructor mypy cannot read:
# mypy: disable-error-code="type-arg,assignment,arg-type"
"""ROS 2 message types as Cyclone DDS IDL structs, and readings turned into them.

The structs carry the DDS type names a ROS 2 node uses (``geometry_msgs::msg::dds_::
WrenchStamped_`` ...), so an ordinary ROS 2 subscriber on Cyclone DDS or any other RMW
matches them without this package needing a ROS installation. Serialised with
``IdlStruct.serialize()`` they are plain CDR (XCDR1, little-endian, 4-byte encapsulation
header ``00 01 00 00``): the bytes ``ros2 bag`` stores in an MCAP file with the ``cdr``
message encoding.

Header stamps are ROS time from :class:`~tactile_force.edge.outputs.ros2_names.StampClock`.
"""

# No 'from __future__ import annotations': cyclonedds reads the field types at class creation.
import enum
import math
from dataclasses import dataclass, field

from ..errors import require

require("cyclonedds", "ros2", "the ROS 2 messages (CDR encoding)")  # names the extra where it is missing

from cyclonedds.idl import IdlStruct  # noqa: E402
from cyclonedds.idl.types import byte, float64, int32, sequence, uint8, uint32  # noqa: E402

from ..reading import Flags, ForceReading  # noqa: E402
from .ros2_names import StampClock  # noqa: E402


# -- the ROS 2 types --------------------------------------------------------------------------
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    """builtin_interfaces/msg/Time: seconds and nanoseconds since the epoch (ROS time)."""

    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    """std_msgs/msg/Header: stamp and the frame the data is expressed in (here: the sensor name)."""

    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    """geometry_msgs/msg/Vector3."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Wrench(IdlStruct, typename="geometry_msgs::msg::dds_::Wrench_"):
    """geometry_msgs/msg/Wrench: force (N) and torque (N m)."""

    force: Vector3 = field(default_factory=Vector3)
    torque: Vector3 = field(default_factory=Vector3)


@dataclass
class WrenchStamped(IdlStruct, typename="geometry_msgs::msg::dds_::WrenchStamped_"):
    """geometry_msgs/msg/WrenchStamped."""

    header: Header = field(default_factory=Header)
    wrench: Wrench = field(default_factory=Wrench)


@dataclass
class Vector3Stamped(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3Stamped_"):
    """geometry_msgs/msg/Vector3Stamped (a reading's interval: x low, y estimate, z high, N)."""

    header: Header = field(default_factory=Header)
    vector: Vector3 = field(default_factory=Vector3)


@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    """diagnostic_msgs/msg/KeyValue."""

    key: str = ""
    value: str = ""


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    """diagnostic_msgs/msg/DiagnosticStatus (level: 0 OK, 1 WARN, 2 ERROR, 3 STALE)."""

    level: byte = 0  # 'byte' in the .msg, 'octet' in IDL
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: sequence[KeyValue] = field(default_factory=list)


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    """diagnostic_msgs/msg/DiagnosticArray."""

    header: Header = field(default_factory=Header)
    status: sequence[DiagnosticStatus] = field(default_factory=list)


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    """sensor_msgs/msg/CompressedImage: ``format`` 'jpeg' or 'png', ``data`` the encoded bytes
    (bytes when written; a list of ints when decoded)."""

    header: Header = field(default_factory=Header)
    format: str = ""
    data: sequence[uint8] = field(default_factory=bytes)


#: ROS 2 type names (as ``ros2 topic echo`` and MCAP schemas name them).
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
DIAGNOSTIC_ARRAY = "diagnostic_msgs/msg/DiagnosticArray"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
VECTOR3_STAMPED = "geometry_msgs/msg/Vector3Stamped"

# -- .msg definitions, concatenated as ros2 bag writes them into MCAP 'ros2msg' schemas ------
_SEP = "=" * 80 + "\n"
_TIME = "int32 sec\nuint32 nanosec\n"
_HEADER = "builtin_interfaces/Time stamp\nstring frame_id\n"
_VECTOR3 = "float64 x\nfloat64 y\nfloat64 z\n"


def _schema(top: str, deps: list[tuple[str, str]]) -> str:
    return top + "".join(f"{_SEP}MSG: {name}\n{text}" for name, text in deps)


#: ROS 2 type name -> its ``ros2msg`` schema text (the message, then every type it uses).
MSG_DEFINITIONS: dict[str, str] = {
    WRENCH_STAMPED: _schema("std_msgs/Header header\ngeometry_msgs/Wrench wrench\n", [
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
        ("geometry_msgs/Wrench", "geometry_msgs/Vector3 force\ngeometry_msgs/Vector3 torque\n"),
        ("geometry_msgs/Vector3", _VECTOR3)]),
    DIAGNOSTIC_ARRAY: _schema("std_msgs/Header header\ndiagnostic_msgs/DiagnosticStatus[] status\n", [
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
        ("diagnostic_msgs/DiagnosticStatus",
         ("byte OK=0\nbyte WARN=1\nbyte ERROR=2\nbyte STALE=3\nbyte level\nstring name\nstring message\n"
          "string hardware_id\ndiagnostic_msgs/KeyValue[] values\n")),
        ("diagnostic_msgs/KeyValue", "string key\nstring value\n")]),
    VECTOR3_STAMPED: _schema("std_msgs/Header header\ngeometry_msgs/Vector3 vector\n", [
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME), ("geometry_msgs/Vector3", _VECTOR3)]),
    COMPRESSED_IMAGE: _schema("std_msgs/Header header\nstring format\nuint8[] data\n", [
        ("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME)]),
}


# -- readings -> messages ------------------------------------------------------------------------
class DiagnosticLevel(enum.IntEnum):
    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


_WARN_FLAGS = Flags.BELOW_RANGE | Flags.SATURATED | Flags.LATE | Flags.STALE


def _stamp(clock: StampClock, monotonic_ns: int) -> Time:
    sec, nanosec = clock.sec_nanosec(monotonic_ns)
    return Time(sec=sec, nanosec=nanosec)


def diagnostic_level(flags: Flags) -> DiagnosticLevel:
    """ERROR for invalid input, WARN for below-range / saturated / late / stale, else OK
    (no contact is a normal state)."""
    if flags & Flags.INVALID_INPUT:
        return DiagnosticLevel.ERROR
    if flags & _WARN_FLAGS:
        return DiagnosticLevel.WARN
    return DiagnosticLevel.OK


def wrench_message(r: ForceReading, clock: StampClock) -> WrenchStamped:
    """WrenchStamped of a reading: stamp = frame time, frame_id = sensor name,
    force.z = normal force in N (NaN when there is no estimate); the rest 0."""
    return WrenchStamped(header=Header(stamp=_stamp(clock, r.timestamp_ns), frame_id=r.sensor),
                         wrench=Wrench(force=Vector3(0.0, 0.0, float(r.force_n))))


def interval_message(r: ForceReading, clock: StampClock) -> Vector3Stamped:
    """Vector3Stamped of a reading's interval, for plots (N): x = force_low_n, y = force_n,
    z = force_high_n; +inf in z when open above (saturated), NaN in x and z when unknown."""
    return Vector3Stamped(header=Header(stamp=_stamp(clock, r.timestamp_ns), frame_id=r.sensor),
                          vector=Vector3(float(r.force_low_n), float(r.force_n), float(r.force_high_n)))


def _num(v: float | None) -> str:
    if v is None:
        return ""
    return "nan" if math.isnan(v) else repr(float(v))


def diagnostic_message(r: ForceReading, clock: StampClock, node: str = "tactile_force") -> DiagnosticArray:
    """DiagnosticArray with one status for a reading: level from its flags, message the flag
    names ('ok' when none) and detail, values the flags, frame index, forces (N) with the
    interval (``force_low_n``, ``force_high_n``: 'nan' when unknown, 'inf' when open above;
    ``interval``: known / open_above / unknown), contact area (pixels) and per-stage latency (ms)."""
    names = r.flags.names()
    message = ",".join(names) or "ok"
    if r.detail:
        message += f": {r.detail}"
    lat = r.latency
    values = [KeyValue("flags", "|".join(names)), KeyValue("flags_int", str(int(r.flags))),
              KeyValue("frame_index", str(r.frame_index)), KeyValue("force_n", _num(r.force_n)),
              KeyValue("force_low_n", _num(r.force_low_n)), KeyValue("force_high_n", _num(r.force_high_n)),
              KeyValue("interval", r.interval.value),
              KeyValue("raw_force_n", _num(r.raw_force_n)), KeyValue("truth_n", _num(r.truth_n)),
              KeyValue("contact_area_px", str(r.contact_area_px)),
              KeyValue("source_ms", _num(lat.source_ms)), KeyValue("gate_ms", _num(lat.gate_ms)),
              KeyValue("depth_ms", _num(lat.depth_ms)), KeyValue("inference_ms", _num(lat.inference_ms)),
              KeyValue("total_ms", _num(lat.total_ms))]
    status = DiagnosticStatus(level=int(diagnostic_level(r.flags)), name=f"{node}: {r.sensor}", message=message,
                              hardware_id=r.sensor, values=values)
    return DiagnosticArray(header=Header(stamp=_stamp(clock, r.timestamp_ns), frame_id=r.sensor), status=[status])


def compressed_image(sensor: str, timestamp_ns: int, data: bytes, fmt: str, clock: StampClock) -> CompressedImage:
    """CompressedImage of already-encoded image bytes (``fmt`` 'jpeg' or 'png')."""
    return CompressedImage(header=Header(stamp=_stamp(clock, timestamp_ns), frame_id=sensor), format=fmt,
                           data=bytes(data))


def reading_payloads(r: ForceReading, clock: StampClock, topic: str) -> list[tuple[str, str, bytes]]:
    """(ROS 2 topic, type name, CDR bytes) of a reading: WrenchStamped on ``topic``,
    DiagnosticArray on ``topic + '/diagnostics'`` and the interval as Vector3Stamped on
    ``topic + '/interval'`` (``topic`` absolute, already checked)."""
    return [(topic, WRENCH_STAMPED, wrench_message(r, clock).serialize()),
            (topic + "/diagnostics", DIAGNOSTIC_ARRAY, diagnostic_message(r, clock).serialize()),
            (topic + "/interval", VECTOR3_STAMPED, interval_message(r, clock).serialize())]
