"""Publish readings on ROS 2 topics through Eclipse Cyclone DDS (the ``ros2`` extra).

Each reading goes out as ``geometry_msgs/msg/WrenchStamped`` on ``topic`` (DDS topic
``rt`` + topic, type ``geometry_msgs::msg::dds_::WrenchStamped_``) and, unless turned off,
its flags and per-stage latency as ``diagnostic_msgs/msg/DiagnosticArray`` on
``topic + '/diagnostics'``, and its interval as ``geometry_msgs/msg/Vector3Stamped`` on
``topic + '/interval'`` (x low, y estimate, z high, N). An ordinary ROS 2 node subscribes to them; no ROS
installation is needed here.

Network: Cyclone DDS reads its configuration from ``CYCLONEDDS_URI`` when the first
participant of a domain is made (tests point it at tests/cyclonedds_loopback.xml).
"""

from __future__ import annotations

import enum
import os
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ..errors import SceneError, require
from ..reading import ForceReading
from .ros2_names import StampClock, dds_topic, ros_topic

#: DDS allows domain ids 0..232 (ROS 2 recommends 0..101 on Linux).
MAX_DOMAIN_ID = 232


class QosProfile(str, enum.Enum):
    """ROS 2 QoS presets: ``sensor_data`` (best effort, keep last 5, volatile; rclcpp's
    SensorDataQoS) or ``reliable`` (reliable, keep last 10, volatile; the ROS 2 default)."""

    SENSOR_DATA = "sensor_data"
    RELIABLE = "reliable"

    @classmethod
    def parse(cls, value: str | QosProfile) -> QosProfile:
        try:
            return cls(value)
        except ValueError:
            raise SceneError(f"ROS 2 qos {value!r}: expected one of {[q.value for q in cls]}") from None


def domain_from_env(domain_id: int | None = None, env: Mapping[str, str] | None = None) -> int:
    """``domain_id`` when given, else ``ROS_DOMAIN_ID`` from the environment, else 0;
    SceneError (a ValueError) naming the source when it is not an integer in 0..232."""
    if domain_id is None:
        text = (os.environ if env is None else env).get("ROS_DOMAIN_ID", "").strip()
        if not text:
            return 0
        try:
            domain_id = int(text)
        except ValueError:
            raise SceneError(f"ROS_DOMAIN_ID={text!r}: expected an integer 0..{MAX_DOMAIN_ID}") from None
        what = "ROS_DOMAIN_ID"
    else:
        what = "ROS 2 domain id"
    if isinstance(domain_id, bool) or not isinstance(domain_id, int) or not 0 <= domain_id <= MAX_DOMAIN_ID:
        raise SceneError(f"{what} {domain_id!r}: expected an integer 0..{MAX_DOMAIN_ID}")
    return domain_id


def dds_qos(profile: QosProfile):
    """The Cyclone DDS Qos of a profile, with XCDR1 data representation (what ROS 2 RMWs speak)."""
    from cyclonedds.qos import Policy, Qos

    rep = Policy.DataRepresentation(use_cdrv0_representation=True)
    if profile is QosProfile.SENSOR_DATA:
        return Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(5), Policy.Durability.Volatile, rep)
    from cyclonedds.util import duration

    return Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
               Policy.Durability.Volatile, rep)


@dataclass(frozen=True, slots=True)
class Ros2Topics:
    """The ROS 2 topic names a publisher uses (absolute) and their DDS names."""

    force: str
    diagnostics: str | None
    interval: str | None = None

    @property
    def dds_force(self) -> str:
        return dds_topic(self.force)

    @property
    def dds_diagnostics(self) -> str | None:
        return dds_topic(self.diagnostics) if self.diagnostics else None

    @property
    def dds_interval(self) -> str | None:
        return dds_topic(self.interval) if self.interval else None


class Ros2Publisher:
    """A reading sink that publishes on ROS 2 topics over Cyclone DDS.

    Parameters
    ----------
    topic : str
        ROS 2 topic of the WrenchStamped messages, e.g. '/tactile/force' (made absolute).
    domain_id : int, optional
        DDS domain; default ``ROS_DOMAIN_ID`` or 0.
    qos : str
        'sensor_data' (default: best effort, keep last 5, volatile) or 'reliable'.
    diagnostics : bool
        Also publish DiagnosticArray (flags, latency) on ``topic + '/diagnostics'``.
    interval : bool
        Also publish the reading's interval as Vector3Stamped on ``topic + '/interval'``
        (x = force_low_n, y = force_n, z = force_high_n; inf / NaN as in the reading).
    stamp_clock : StampClock, optional
        Monotonic frame time -> ROS time; default the wall - monotonic offset at start.

    Raises SceneError (a ValueError) for a bad topic, qos or domain, or when Cyclone DDS
    cannot start (a bad ``CYCLONEDDS_URI``); MissingExtraError (an ImportError
    naming the ``ros2`` extra) when cyclonedds is not installed.
    """

    def __init__(self, topic: str, *, domain_id: int | None = None, qos: str = "sensor_data",
                 diagnostics: bool = True, stamp_clock: StampClock | None = None, interval: bool = True) -> None:
        force = ros_topic(topic, "--ros2 topic")
        self.topics = Ros2Topics(force, force + "/diagnostics" if diagnostics else None,
                                 force + "/interval" if interval else None)
        self.qos = QosProfile.parse(qos)
        self.domain_id = domain_from_env(domain_id)
        self.clock = stamp_clock or StampClock()
        self.published = 0
        require("cyclonedds", "ros2", "ROS 2 output")
        from cyclonedds.domain import DomainParticipant
        from cyclonedds.pub import DataWriter
        from cyclonedds.topic import Topic

        from .ros2_messages import (
            DiagnosticArray,
            Vector3Stamped,
            WrenchStamped,
            diagnostic_message,
            interval_message,
            wrench_message,
        )

        self._wrench_message, self._diagnostic_message = wrench_message, diagnostic_message
        self._interval_message = interval_message

        from cyclonedds.core import DDSException

        q = dds_qos(self.qos)
        try:
            self._participant: Any = DomainParticipant(self.domain_id)
        except DDSException as exc:
            uri = os.environ.get("CYCLONEDDS_URI", "")
            raise SceneError(f"ROS 2 output on domain {self.domain_id}: Cyclone DDS cannot start ({exc}); "
                             f"check CYCLONEDDS_URI={uri!r}" if uri else
                             f"ROS 2 output on domain {self.domain_id}: Cyclone DDS cannot start ({exc})") from None
        self._force: Any = DataWriter(self._participant, Topic(self._participant, self.topics.dds_force, WrenchStamped,
                                                          qos=q), qos=q)
        self._diag: Any = None
        if self.topics.dds_diagnostics:
            self._diag = DataWriter(self._participant, Topic(self._participant, self.topics.dds_diagnostics,
                                                             DiagnosticArray, qos=q), qos=q)
        self._interval: Any = None
        if self.topics.dds_interval:
            self._interval = DataWriter(self._participant, Topic(self._participant, self.topics.dds_interval,
                                                                 Vector3Stamped, qos=q), qos=q)
        self._closed = False

    def write(self, reading: ForceReading) -> None:
        """Publish one reading (WrenchStamped, then DiagnosticArray, then the interval)."""
        if self._closed:
            raise RuntimeError(f"ROS 2 publisher on {self.topics.force}: write after close")
        self._force.write(self._wrench_message(reading, self.clock))
        if self._diag is not None:
            self._diag.write(self._diagnostic_message(reading, self.clock))
        if self._interval is not None:
            self._interval.write(self._interval_message(reading, self.clock))
        self.published += 1

    def close(self) -> None:
        """Delete the DDS writers and participant; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._diag = None
        self._interval = None
        self._force = None
        participant, self._participant = self._participant, None
        # The binding deletes an entity when its Python object goes; the participant's
        # deletion takes its writers and topics with it (subscribers see them leave).
        participant.__del__()

    def __enter__(self) -> Ros2Publisher:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
