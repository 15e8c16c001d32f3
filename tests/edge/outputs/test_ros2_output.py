"""ROS 2 output over real Cyclone DDS, on the loopback interface only.

CYCLONEDDS_URI points at tests/cyclonedds_loopback.xml (interface lo, multicast off, the
one peer 127.0.0.1) from the moment this module is imported, before any participant
exists; every test run uses its own random domain id so parallel runs do not cross.
A real Cyclone DDS DataReader subscribes as a ROS 2 node would and decodes the messages.
"""

from __future__ import annotations

import math
import os
import random
import subprocess
import time
from pathlib import Path

import pytest

from tests.conftest import CYCLONEDDS_LOOPBACK as LOOPBACK_XML  # noqa: E402
os.environ["CYCLONEDDS_URI"] = LOOPBACK_XML.as_uri()  # before any participant exists in this process

pytest.importorskip("cyclonedds", reason="ROS 2 output needs cyclonedds (the 'ros2' extra)")

from cyclonedds.core import DDSException  # noqa: E402
from cyclonedds.domain import DomainParticipant  # noqa: E402
from cyclonedds.qos import Policy, Qos  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402
from cyclonedds.util import duration  # noqa: E402
from tactile_force.edge.outputs.ros2_messages import DiagnosticArray, WrenchStamped  # noqa: E402
from tactile_force.edge.outputs.ros2_names import StampClock, dds_topic, ros_topic  # noqa: E402
from tactile_force.edge.outputs.ros2_topic import (  # noqa: E402
    QosProfile,
    Ros2Publisher,
    dds_qos,
    domain_from_env,
)
from tactile_force.edge.reading import Flags, ForceReading, StageLatency  # noqa: E402

SENSOR_QOS = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(50), Policy.Durability.Volatile)


@pytest.fixture(scope="module")
def domain() -> int:
    """A random DDS domain id for this run (1..230), so concurrent runs never see each other."""
    assert os.environ["CYCLONEDDS_URI"] == LOOPBACK_XML.as_uri() and LOOPBACK_XML.is_file()
    return random.SystemRandom().randint(1, 230)


def _wait(cond, timeout_s: float = 10.0) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(0.02)
    return False


def _reading(i: int, force: float, flags: Flags, sensor: str = "left") -> ForceReading:
    return ForceReading(sensor, 1_000_000_000 * (i + 1) + 123, i, force, flags,
                        StageLatency(0.5, 0.25, 0.0, 1.5, 2.75 + i), raw_force_n=force, contact_area_px=100 * i,
                        truth_n=4.0 if i == 1 else None, detail="")


def test_topic_names_and_bad_input():
    assert ros_topic("tactile/force") == "/tactile/force"
    assert dds_topic("/tactile/force") == "rt/tactile/force"
    for bad in ("", "/", "/tactile//force", "/1force", "/tac-tile", "/force/"):
        with pytest.raises(ValueError, match="ROS 2"):
            ros_topic(bad)
    assert domain_from_env(None, {}) == 0
    assert domain_from_env(None, {"ROS_DOMAIN_ID": " 42 "}) == 42
    assert domain_from_env(7, {"ROS_DOMAIN_ID": "42"}) == 7
    with pytest.raises(ValueError, match="ROS_DOMAIN_ID='x'"):
        domain_from_env(None, {"ROS_DOMAIN_ID": "x"})
    with pytest.raises(ValueError, match="233"):
        domain_from_env(233)
    with pytest.raises(ValueError, match="qos 'fast'"):
        Ros2Publisher("/tactile/force", qos="fast", domain_id=0)


def test_messages_serialise_as_plain_cdr():
    clock = StampClock(offset_ns=0)
    from tactile_force.edge.outputs.ros2_messages import wrench_message

    data = wrench_message(_reading(2, 3.25, Flags.NONE), clock).serialize()
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR_LE encapsulation, what ROS 2 RMWs and ros2 bag use
    assert WrenchStamped.__idl_typename__ == "geometry_msgs::msg::dds_::WrenchStamped_"
    back = WrenchStamped.deserialize(data)
    assert (back.header.stamp.sec, back.header.stamp.nanosec, back.header.frame_id) == (3, 123, "left")
    assert back.wrench.force.z == 3.25


def test_subscriber_receives_wrench_and_diagnostics(domain):
    clock = StampClock(offset_ns=10_000_000_000)
    readings = [_reading(0, 0.0, Flags.NO_CONTACT), _reading(1, 4.5, Flags.NONE),
                _reading(2, math.nan, Flags.INVALID_INPUT), _reading(3, 15.0, Flags.SATURATED | Flags.LATE)]
    sub = DomainParticipant(domain)
    wrench_reader = DataReader(sub, Topic(sub, "rt/tactile/force", WrenchStamped, qos=SENSOR_QOS), qos=SENSOR_QOS)
    diag_reader = DataReader(sub, Topic(sub, "rt/tactile/force/diagnostics", DiagnosticArray, qos=SENSOR_QOS),
                             qos=SENSOR_QOS)
    with Ros2Publisher("/tactile/force", domain_id=domain, stamp_clock=clock) as pub:
        assert (pub.topics.dds_force, pub.topics.dds_diagnostics) == ("rt/tactile/force",
                                                                      "rt/tactile/force/diagnostics")
        assert _wait(lambda: pub._force.get_publication_matched_status().current_count == 1
                     and pub._diag.get_publication_matched_status().current_count == 1), "no subscriber matched"
        assert wrench_reader.topic.typename == "geometry_msgs::msg::dds_::WrenchStamped_"
        assert diag_reader.topic.typename == "diagnostic_msgs::msg::dds_::DiagnosticArray_"
        for r in readings:
            pub.write(r)
        wrenches: list = []
        diags: list = []
        assert _wait(lambda: (wrenches.extend(wrench_reader.take(N=10)), diags.extend(diag_reader.take(N=10)),
                              len(wrenches) >= 4 and len(diags) >= 4)[-1]), f"got {len(wrenches)}, {len(diags)}"
    assert pub.published == 4
    for r, w, d in zip(readings, wrenches, diags):
        assert (w.header.stamp.sec, w.header.stamp.nanosec) == (r.timestamp_ns // 10**9 + 10, 123)
        assert w.header.frame_id == "left" and d.header.frame_id == "left"
        assert (w.wrench.force.x, w.wrench.force.y) == (0.0, 0.0) and w.wrench.torque.z == 0.0
        assert (math.isnan(w.wrench.force.z) and math.isnan(r.force_n)) or w.wrench.force.z == r.force_n
        (status,) = d.status
        values = {kv.key: kv.value for kv in status.values}
        assert values["flags"] == "|".join(r.flags.names()) and int(values["flags_int"]) == int(r.flags)
        assert float(values["total_ms"]) == r.latency.total_ms and float(values["inference_ms"]) == 1.5
        assert values["frame_index"] == str(r.frame_index)
        assert status.hardware_id == "left"
    assert [d.status[0].level for d in diags] == [0, 0, 2, 1]  # no contact OK, invalid ERROR, saturated WARN
    assert diags[2].status[0].message.startswith("invalid_input")
    assert {kv.key: kv.value for kv in diags[1].status[0].values}["truth_n"] == "4.0"


def test_every_sensor_of_a_hand_reaches_a_subscriber(domain, aurova_dir):
    """A runtime serving four sensors publishes every reading on the one topic, each with its
    sensor's name as frame_id and its own frame time."""
    from tests.edge.outputs.test_many_sensor_outputs import NAMES, four_finger_runtime

    deep = Qos(Policy.Reliability.BestEffort, Policy.History.KeepLast(200), Policy.Durability.Volatile)
    sub = DomainParticipant(domain)
    reader = DataReader(sub, Topic(sub, "rt/hand/force", WrenchStamped, qos=deep), qos=deep)
    clock = StampClock(offset_ns=0)
    rt = four_finger_runtime(aurova_dir)
    readings: list = []
    got: list = []
    with Ros2Publisher("/hand/force", domain_id=domain, stamp_clock=clock, diagnostics=False,
                       interval=False) as pub:
        assert _wait(lambda: pub._force.get_publication_matched_status().current_count == 1), "no subscriber matched"
        rt.run([pub], on_reading=readings.append)
        assert _wait(lambda: (got.extend(reader.take(N=100)), len(got) >= len(readings))[-1]), f"got {len(got)}"
    rt.close()
    assert len(readings) == 4 * 11
    for name in NAMES:
        want = [divmod(r.timestamp_ns, 10**9) for r in readings if r.sensor == name]
        assert [(w.header.stamp.sec, w.header.stamp.nanosec) for w in got if w.header.frame_id == name] == want


def test_reliable_default_qos_subscriber_does_not_match_sensor_data(domain):
    """What docs/ros2.md warns about: a reliable (default-QoS) subscriber never matches the
    best-effort sensor-data writer; with qos='reliable' it does."""
    sub = DomainParticipant(domain)
    reliable = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10))
    reader = DataReader(sub, Topic(sub, "rt/qos_check/force", WrenchStamped, qos=reliable), qos=reliable)
    with Ros2Publisher("/qos_check/force", domain_id=domain, diagnostics=False) as pub:
        assert pub._diag is None
        assert _wait(lambda: reader.get_requested_incompatible_qos_status().total_count >= 1), "no QoS mismatch seen"
        assert reader.get_subscription_matched_status().current_count == 0
    with Ros2Publisher("/qos_check/force", domain_id=domain, qos="reliable", diagnostics=False) as pub:
        assert _wait(lambda: reader.get_subscription_matched_status().current_count == 1)
        pub.write(_reading(0, 2.0, Flags.NONE))
        got: list = []
        assert _wait(lambda: bool(got.extend(reader.take(N=5)) or got))
        assert got[0].wrench.force.z == 2.0
    assert dds_qos(QosProfile.SENSOR_DATA) != dds_qos(QosProfile.RELIABLE)


def test_write_after_close_is_refused(domain):
    pub = Ros2Publisher("/closed/force", domain_id=domain)
    pub.close()
    pub.close()
    with pytest.raises(RuntimeError, match="after close"):
        pub.write(_reading(0, 1.0, Flags.NONE))


def test_participant_stays_on_loopback(tmp_path, monkeypatch):
    """Cyclone's own trace of the loopback config: only 'lo' is selected, its address is
    127.0.0.1, the only peers are 127.0.0.1, multicast is off; our sockets talk to no
    other address."""
    trace = tmp_path / "cyclonedds.log"
    monkeypatch.setenv("CYCLONEDDS_URI", f"{LOOPBACK_XML.as_uri()},<Tracing><Verbosity>config</Verbosity>"
                                         f"<OutputFile>{trace}</OutputFile></Tracing>")
    dom = random.SystemRandom().randint(1, 230)
    with Ros2Publisher("/loopback/force", domain_id=dom) as pub:
        pub.write(_reading(0, 1.0, Flags.NONE))
        text = trace.read_text()
        try:
            ss = subprocess.run(["ss", "-uanpH"], check=False, capture_output=True, text=True, timeout=10).stdout
        except (OSError, subprocess.SubprocessError):
            ss = ""
    assert "selected interfaces: lo " in text and "ownip: udp/127.0.0.1" in text
    assert "Domain/General/AllowMulticast/#text: false" in text
    peers = [ln for ln in text.splitlines() if "add_peer_address" in ln]
    assert peers and all("udp/127.0.0.1:" in ln for ln in peers)
    for line in ss.splitlines():
        if f"pid={os.getpid()}," in line:
            local, peer = line.split()[3], line.split()[4]
            assert local.rsplit(":", 1)[0] in ("0.0.0.0", "127.0.0.1", "*"), line  # receive sockets, lo traffic only
            assert peer.rsplit(":", 1)[0] in ("0.0.0.0", "127.0.0.1", "*"), line


def test_missing_cyclonedds_names_the_extra(monkeypatch):
    import sys

    from tactile_force.edge.errors import MissingExtraError

    monkeypatch.setitem(sys.modules, "cyclonedds", None)  # as if not installed: import raises ImportError
    with pytest.raises(MissingExtraError, match=r"tactile-force\[ros2\]"):
        Ros2Publisher("/x/force", domain_id=0)


def test_domain_participant_errors_surface(domain):
    with pytest.raises((ValueError, DDSException)):
        Ros2Publisher("/x/force", domain_id=-1)
