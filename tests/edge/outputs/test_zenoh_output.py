"""The Zenoh output (ROS 2 on rmw_zenoh) over real Zenoh, on 127.0.0.1 only.

Every router here is started by the test (an eclipse-zenoh session in router mode, in this
process or in a child process) on ``tcp/127.0.0.1:<free port>`` with multicast scouting
off; the subscribers are clients of it. What is published is read back by implementations
that are not this package's:

- zenoh-ros2-sdk (its discovery, its subscriber, its key expression, token and attachment
  code) with the message definitions and type hashes given, so nothing is fetched;
- rosbags: its RIHS01 type hashes and its CDR decoder over its own ROS 2 Jazzy / Kilted
  message definitions.
"""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading
import time
from collections import defaultdict
from dataclasses import fields
from pathlib import Path

import pytest

zenoh = pytest.importorskip("zenoh", reason="the Zenoh output needs eclipse-zenoh (the 'zenoh' extra; "
                                            "pip install '.[dev]' installs it)")
pytest.importorskip("cyclonedds", reason="the Zenoh output encodes CDR with cyclonedds (the 'zenoh' extra)")
pytest.importorskip("rosbags", reason="the independent RIHS01 / CDR decoder rosbags (the 'dev' extra)")
pytest.importorskip("zenoh_ros2_sdk", reason="the independent rmw_zenoh decoder zenoh-ros2-sdk (the 'dev' extra)")

from rosbags.typesys import Stores, get_typestore  # noqa: E402
from tactile_force.edge.cli import main as cli_main  # noqa: E402
from tactile_force.edge.errors import SceneError  # noqa: E402
from tactile_force.edge.outputs import ros2_messages  # noqa: E402
from tactile_force.edge.outputs.ros2_messages import (  # noqa: E402
    DIAGNOSTIC_ARRAY,
    MSG_DEFINITIONS,
    VECTOR3_STAMPED,
    WRENCH_STAMPED,
)
from tactile_force.edge.outputs.ros2_names import StampClock  # noqa: E402
from tactile_force.edge.outputs.ros2_type_hash import rihs01, split_definition, type_fields  # noqa: E402
from tactile_force.edge.outputs.zenoh_topic import ZenohPublisher  # noqa: E402
from tactile_force.edge.outputs.zenoh_wire import NodeName, WireQos, attachment, topic_key  # noqa: E402
from tactile_force.edge.reading import Flags, ForceReading, StageLatency  # noqa: E402
from tactile_force.edge.scene import scene_from_flags  # noqa: E402
from tactile_force.edge.scene.describe import scene_to_toml  # noqa: E402
from zenoh_ros2_sdk import ROS2Subscriber, ZenohSession  # noqa: E402
from zenoh_ros2_sdk import discovery as sdk_discovery  # noqa: E402
from zenoh_ros2_sdk import session as sdk_session_module  # noqa: E402
from zenoh_ros2_sdk import subscriber as sdk_subscriber_module  # noqa: E402
from zenoh_ros2_sdk.attachment import Attachment  # noqa: E402
from zenoh_ros2_sdk.entity import EndpointEntity, EntityKind, NodeEntity  # noqa: E402
from zenoh_ros2_sdk.keyexpr import endpoint_liveliness_keyexpr, node_liveliness_keyexpr, topic_keyexpr  # noqa: E402
from zenoh_ros2_sdk.qos import QosProfile as SdkQos  # noqa: E402
from zenoh_ros2_sdk.qos import QosReliability  # noqa: E402
from zenoh_ros2_sdk.utils import compute_type_hash_from_msg, ros2_to_dds_type  # noqa: E402

from tests.conftest import REPO  # noqa: E402

TYPES = [WRENCH_STAMPED, DIAGNOSTIC_ARRAY, VECTOR3_STAMPED]
#: Router code for a child process: router mode on argv[1], multicast off, until SIGTERM / SIGKILL.
ROUTER = textwrap.dedent("""
    import json, signal, sys, zenoh
    c = zenoh.Config()
    c.insert_json5("mode", '"router"')
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("scouting/gossip/enabled", "false")
    c.insert_json5("listen/endpoints", json.dumps([sys.argv[1]]))
    s = zenoh.open(c)
    print("ready", flush=True)
    signal.sigwait([signal.SIGTERM, signal.SIGINT])
""")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _config(mode: str, endpoint: str) -> zenoh.Config:
    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("scouting/gossip/enabled", "false")
    key = "listen/endpoints" if mode == "router" else "connect/endpoints"
    c.insert_json5(key, json.dumps([endpoint]))
    if mode == "client":  # come back quickly when a router restarts
        c.insert_json5("connect/retry", '{period_init_ms: 100, period_max_ms: 500, period_increase_factor: 2}')
    return c


def open_router(endpoint: str):
    return zenoh.open(_config("router", endpoint))


def open_client(endpoint: str):
    return zenoh.open(_config("client", endpoint))


def wait_for(cond, timeout_s: float = 20.0, step_s: float = 0.02) -> bool:
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        if cond():
            return True
        time.sleep(step_s)
    return bool(cond())


@pytest.fixture
def router():
    """An in-process Zenoh router on 127.0.0.1: its endpoint and port."""
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    session = open_router(endpoint)
    yield endpoint, port
    session.close()


@pytest.fixture
def sdk(router, monkeypatch):
    """zenoh-ros2-sdk's shared session, a client of the test's router (its singleton is
    closed afterwards so the next test gets its own)."""
    monkeypatch.setenv("ZENOH_CONFIG_OVERRIDE", 'mode="client";scouting/multicast/enabled=false')
    monkeypatch.delenv("ZENOH_SESSION_CONFIG_URI", raising=False)

    def no_fetch(*a, **k):
        raise AssertionError("zenoh-ros2-sdk would fetch message definitions; every one is given here")

    for module in (sdk_session_module, sdk_subscriber_module):
        monkeypatch.setattr(module, "get_registry", no_fetch)
    ZenohSession._instance = None
    session = ZenohSession.get_instance("127.0.0.1", router[1])
    yield session
    session.close()
    ZenohSession._instance = None


def sdk_hash(ros_type: str) -> str:
    """zenoh-ros2-sdk's RIHS01 of a type, from the .msg texts this package encodes."""
    parts = split_definition(ros_type, MSG_DEFINITIONS[ros_type])
    return compute_type_hash_from_msg(ros_type, parts.pop(ros_type), parts)


# -- type hashes ----------------------------------------------------------------------------
@pytest.mark.parametrize("ros_type", sorted(MSG_DEFINITIONS))
def test_type_hashes_match_rosbags_and_zenoh_ros2_sdk(ros_type):
    ours = rihs01(ros_type)
    assert ours.startswith("RIHS01_") and len(ours) == 7 + 64
    # rosbags over its own copies of the ROS 2 Jazzy and Kilted definitions
    for store in (Stores.ROS2_JAZZY, Stores.ROS2_KILTED):
        assert get_typestore(store).hash_rihs01(ros_type) == ours, store
    assert sdk_hash(ros_type) == ours


def test_hashed_fields_are_the_encoded_fields():
    """The .msg texts hashed name the fields the IDL structs serialise, in their order."""
    structs = {f"{c.__idl_typename__.split('::')[0]}/msg/{c.__name__}": c
               for c in vars(ros2_messages).values() if hasattr(c, "__idl_typename__")}
    checked = 0
    for ros_type, text in MSG_DEFINITIONS.items():
        for name, body in split_definition(ros_type, text).items():
            assert [f["name"] for f in type_fields(name, body)] == [f.name for f in fields(structs[name])], name
            checked += 1
    assert checked >= 10


def test_a_changed_definition_changes_the_hash():
    text = MSG_DEFINITIONS[WRENCH_STAMPED]
    assert rihs01(WRENCH_STAMPED, text.replace("float64 z", "float32 z")) != rihs01(WRENCH_STAMPED)
    with pytest.raises(ValueError, match="geometry_msgs/msg/Wrench"):
        rihs01(WRENCH_STAMPED, text.split("=" * 80)[0])


# -- the wire format, against zenoh-ros2-sdk ------------------------------------------------
def test_key_expressions_tokens_qos_and_attachment_match_the_sdk():
    h = rihs01(WRENCH_STAMPED)
    assert topic_key(3, "/left/tactile/force", WRENCH_STAMPED, h) == topic_keyexpr(
        3, "/left/tactile/force", ros2_to_dds_type(WRENCH_STAMPED), h)
    assert topic_key(0, "/tactile/force", WRENCH_STAMPED, h) == (
        f"0/tactile/force/geometry_msgs::msg::dds_::WrenchStamped_/{h}")
    for ns in ("/", "/left_hand", "/fleet/hand_2"):
        name = NodeName(5, ns, "tactile_force", "a1b2c3", node_id=0)
        node = NodeEntity(domain_id=5, session_id="a1b2c3", node_id=0, node_name="tactile_force", namespace=ns)
        assert name.node_token() == node_liveliness_keyexpr(node)
        for qos, sdk_qos in ((WireQos(False, 5), SdkQos(reliability=QosReliability.BEST_EFFORT, history_depth=5)),
                             (WireQos(True, 10), SdkQos(history_depth=10))):
            ep = EndpointEntity(node=node, entity_id=2, kind=EntityKind.PUBLISHER, name="/tactile/force",
                                dds_type_name=ros2_to_dds_type(WRENCH_STAMPED), type_hash=h, qos=sdk_qos.encode())
            assert name.publisher_token(2, "/tactile/force", WRENCH_STAMPED, h, qos) == endpoint_liveliness_keyexpr(ep)
            assert SdkQos.decode(qos.token()) == sdk_qos
    gid = bytes(range(16))
    a = Attachment.from_bytes(attachment(7, 1_700_000_000_123_456_789, gid))
    assert (a.sequence_id, a.timestamp_ns, a.gid) == (7, 1_700_000_000_123_456_789, gid)
    with pytest.raises(ValueError, match="16 bytes"):
        attachment(1, 0, b"short")


# -- graph and delivery ------------------------------------------------------------------------
def _reading(sensor: int, i: int, start_ns: int) -> ForceReading:
    flags = Flags.NO_CONTACT if i % 50 == 0 else Flags(0)
    force = 0.0 if flags else 0.5 + sensor + i / 1000
    return ForceReading(f"s{sensor}", start_ns + round(i * 1e9 / 60), i, force, flags,
                        StageLatency(0.1, 0.2, 0.0, 1.0, 1.5), raw_force_n=force, contact_area_px=i,
                        force_low_n=force - 0.25, force_high_n=force + 0.25)


def test_graph_shows_the_node_and_its_publishers_then_nothing_after_close(router, sdk):
    endpoint, port = router
    lv = open_client(endpoint)
    try:
        with ZenohPublisher("force", namespace="/hands/left", endpoint=endpoint, domain_id=4) as pub:
            topics: dict = {}

            def listed() -> bool:  # the tokens reach the router a moment after they are declared
                topics.update(sdk_discovery.get_topic_names_and_types(domain_id=4, router_port=port, timeout=1.0))
                return len(topics) == 3

            wait_for(listed, 10)
            assert topics == {"/hands/left/force": [WRENCH_STAMPED],
                              "/hands/left/force/diagnostics": [DIAGNOSTIC_ARRAY],
                              "/hands/left/force/interval": [VECTOR3_STAMPED]}
            info = sdk_discovery.get_topic_info("/hands/left/force", domain_id=4, router_port=port, timeout=2.0,
                                                verbose=True)
            assert info is not None and info.publisher_count == 1
            p = info.publishers[0]
            assert (p.node_name, p.node_namespace, p.type_hash) == ("tactile_force", "/hands/left",
                                                                    sdk_hash(WRENCH_STAMPED))
            assert SdkQos.decode(p.qos).reliability is QosReliability.BEST_EFFORT
            nodes = [str(r.ok.key_expr) for r in lv.liveliness().get("@ros2_lv/4/*/*/*/NN/**", timeout=2.0) if r.ok]
            assert nodes == [f"@ros2_lv/4/{pub.zid}/0/0/NN/%/%hands%left/tactile_force"]
        assert wait_for(lambda: not [r for r in lv.liveliness().get("@ros2_lv/4/**", timeout=1.0) if r.ok], 10)
    finally:
        lv.close()


def test_eight_sensors_at_60_fps_for_10_s_arrive_in_order_none_lost(router, sdk):
    """4800 readings (8 sensors x 600 frames, paced at 60 steps a second as a hand's runtime
    writes them), each decoded by zenoh-ros2-sdk's subscribers (rosbags CDR) on all three
    topics, with every sample's key expression and attachment read from a plain Zenoh
    subscriber: in order per sensor, none lost, stamps equal to the frames' times."""
    endpoint, port = router
    n_sensors, n_frames, domain = 8, 600, 6
    got: dict[str, list] = defaultdict(list)
    subs = [ROS2Subscriber(f"/tactile/force{suffix}", ros_type, (lambda m, t=ros_type: got[t].append(m)),
                           msg_definition=MSG_DEFINITIONS[ros_type], type_hash=sdk_hash(ros_type), domain_id=domain,
                           router_port=port, node_name="listener")
            for suffix, ros_type in (("", WRENCH_STAMPED), ("/diagnostics", DIAGNOSTIC_ARRAY),
                                     ("/interval", VECTOR3_STAMPED))]
    raw: list[tuple[str, bytes]] = []
    tap = open_client(endpoint)
    tap.declare_subscriber(f"{domain}/**", lambda s: raw.append((str(s.key_expr), s.attachment.to_bytes())))
    start_ns = 1_000_000_000_000
    wall0 = time.time_ns()
    try:
        with ZenohPublisher("/tactile/force", endpoint=endpoint, domain_id=domain,
                            stamp_clock=StampClock(offset_ns=0)) as pub:
            time.sleep(0.5)  # the subscriptions reach the publisher's session
            t0 = time.monotonic()
            for i in range(n_frames):
                for s in range(n_sensors):
                    pub.write(_reading(s, i, start_ns))
                time.sleep(max(0.0, t0 + (i + 1) / 60 - time.monotonic()))
            assert pub.published == n_sensors * n_frames and pub.dropped == 0
            total = n_sensors * n_frames
            wait_for(lambda: all(len(got[t]) >= total for t in TYPES) and len(raw) >= 3 * total, 20)
    finally:
        for s in subs:
            s.close()
        tap.close()
    wall1 = time.time_ns()

    per_sensor: dict[str, list[int]] = defaultdict(list)
    for m in got[WRENCH_STAMPED]:
        stamp = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
        i = round((stamp - start_ns) * 60 / 1e9)
        assert stamp == start_ns + round(i * 1e9 / 60)  # the frame's own time
        s = int(m.header.frame_id[1:])
        want = _reading(s, i, start_ns)
        assert m.wrench.force.z == want.force_n and m.wrench.force.x == 0.0 and m.wrench.torque.z == 0.0
        per_sensor[m.header.frame_id].append(i)
    counts = {k: len(v) for k, v in sorted(per_sensor.items())}
    print(f"\nWrenchStamped decoded by zenoh-ros2-sdk per sensor: {counts}")
    assert per_sensor == {f"s{s}": list(range(n_frames)) for s in range(n_sensors)}  # in order, none lost
    diag: dict[str, list[int]] = defaultdict(list)
    for m in got[DIAGNOSTIC_ARRAY]:
        values = {kv.key: kv.value for kv in m.status[0].values}
        diag[m.status[0].hardware_id].append(int(values["frame_index"]))
        assert m.status[0].message == ("no_contact" if int(values["frame_index"]) % 50 == 0 else "ok")
    assert diag == {f"s{s}": list(range(n_frames)) for s in range(n_sensors)}
    interval: dict[str, list[float]] = defaultdict(list)
    for m in got[VECTOR3_STAMPED]:
        assert m.vector.x == m.vector.y - 0.25 and m.vector.z == m.vector.y + 0.25
        interval[m.header.frame_id].append(m.vector.y)
    assert {k: len(v) for k, v in interval.items()} == {f"s{s}": n_frames for s in range(n_sensors)}

    by_key: dict[str, list[Attachment]] = defaultdict(list)
    for key, att in raw:
        by_key[key].append(Attachment.from_bytes(att))
    assert sorted(by_key) == sorted(f"{domain}/tactile/force{sfx}/{ros2_to_dds_type(t)}/{sdk_hash(t)}" for sfx, t in
                                    (("", WRENCH_STAMPED), ("/diagnostics", DIAGNOSTIC_ARRAY),
                                     ("/interval", VECTOR3_STAMPED)))
    gids = set()
    for key, atts in by_key.items():
        assert [a.sequence_id for a in atts] == list(range(1, n_sensors * n_frames + 1)), key
        assert all(wall0 <= a.timestamp_ns <= wall1 for a in atts)
        assert len({a.gid for a in atts}) == 1 and len(atts[0].gid) == 16
        gids.add(atts[0].gid)
    assert len(gids) == 3  # one GID per publisher


def test_reliable_qos_is_declared_in_the_publishers_tokens(router):
    endpoint, _ = router
    lv = open_client(endpoint)
    try:
        with ZenohPublisher(endpoint=endpoint, qos="reliable", interval=False, diagnostics=False, domain_id=2):
            keys: list[str] = []

            def declared() -> bool:
                keys[:] = [str(r.ok.key_expr) for r in lv.liveliness().get("@ros2_lv/2/*/*/*/MP/**", timeout=1.0)
                           if r.ok]
                return bool(keys)

            assert wait_for(declared, 10)
        assert len(keys) == 1  # the force topic only
        qos = SdkQos.decode(keys[0].rsplit("/", 1)[1])
        assert (qos.reliability, qos.history_depth) == (QosReliability.RELIABLE, 10)
    finally:
        lv.close()


def test_peer_mode_reaches_a_subscriber_through_the_router(router):
    endpoint, _ = router
    store = get_typestore(Stores.ROS2_JAZZY)
    seen: list = []
    tap = open_client(endpoint)
    tap.declare_subscriber("0/tactile/force/geometry_msgs::msg::dds_::WrenchStamped_/*",
                           lambda s: seen.append(store.deserialize_cdr(s.payload.to_bytes(), WRENCH_STAMPED)))
    try:
        with ZenohPublisher(endpoint=endpoint, mode="peer", domain_id=0, stamp_clock=StampClock(0)) as pub:
            i = 0
            while not seen and i < 2000:  # until the subscription has reached the publisher
                pub.write(_reading(3, i, 10**12))
                i += 1
                time.sleep(0.01)
        assert seen and seen[0].header.frame_id == "s3"
    finally:
        tap.close()


# -- faults --------------------------------------------------------------------------------------
def test_no_router_names_the_endpoint(tmp_path, monkeypatch, capsys):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with pytest.raises(SceneError, match=f"no Zenoh router answers at {endpoint}.*--zenoh-retry"):
        ZenohPublisher(endpoint=endpoint, connect_timeout_s=0.3)
    monkeypatch.chdir(tmp_path)
    rc = cli_main(["run", "--source", "virtual", "--zenoh", endpoint, "--out", "r.csv", "--max-frames", "3"])
    err = capsys.readouterr().err
    assert rc == 2 and endpoint in err and "Traceback" not in err
    assert not (tmp_path / "r.csv").exists()  # the networked output opens first: no half result left
    # with --zenoh-retry the run goes on without a router: the CSV gets every reading
    rc = cli_main(["run", "--source", "virtual", "--zenoh", endpoint, "--zenoh-retry", "--out", "kept.csv",
                   "--max-frames", "12"])
    assert rc == 0, capsys.readouterr().err
    assert [int(r["frame_index"]) for r in csv.DictReader((tmp_path / "kept.csv").open())] == list(range(12))
    rc = cli_main(["run", "--source", "virtual", "--zenoh-namespace", "/x", "--out", "q.csv"])
    assert rc == 2 and "--zenoh-namespace: only with --zenoh" in capsys.readouterr().err


def test_missing_zenoh_names_the_extra(monkeypatch):
    from tactile_force.edge.errors import MissingExtraError

    monkeypatch.setitem(sys.modules, "zenoh", None)
    with pytest.raises(MissingExtraError, match=r"tactile-force\[zenoh\]"):
        ZenohPublisher(endpoint="tcp/127.0.0.1:1")


def test_retry_keeps_running_until_a_router_comes(tmp_path):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    pub = ZenohPublisher(endpoint=endpoint, retry=True, connect_timeout_s=0.3, retry_period_s=0.1,
                         stamp_clock=StampClock(offset_ns=0))
    try:
        for i in range(5):
            pub.write(_reading(0, i, 10**12))
        assert (pub.published, pub.dropped, pub.connected) == (0, 5, False)
        assert wait_for(lambda: pub.last_error is not None, 10) and endpoint in str(pub.last_error)
        router = open_router(endpoint)
        try:
            seen: list[int] = []
            store = get_typestore(Stores.ROS2_JAZZY)
            tap = open_client(endpoint)
            tap.declare_subscriber("0/tactile/force/geometry_msgs::msg::dds_::WrenchStamped_/*", lambda s: seen.append(
                store.deserialize_cdr(s.payload.to_bytes(), WRENCH_STAMPED).header.stamp.nanosec))
            assert wait_for(lambda: pub.connected, 20)
            i = 5
            while not seen and i < 2000:  # until the subscription has reached the publisher
                pub.write(_reading(0, i, 10**12))
                i += 1
                time.sleep(0.01)
            assert seen and pub.dropped == 5
            tap.close()
        finally:
            router.close()
    finally:
        pub.close()


def _start_router(endpoint: str) -> subprocess.Popen:
    p = subprocess.Popen([sys.executable, "-c", ROUTER, endpoint], stdout=subprocess.PIPE, text=True)
    assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    return p


def test_fleet_through_a_router_that_restarts_then_ctrl_c(tmp_path):
    """Two runtimes (processes), each its own namespace, publish through one router (a child
    process). The router is killed and started again mid-run: both publish again within 2 s
    of its return, neither run stops. Ctrl-C then ends both with every output closed: the
    graph loses their nodes and publishers, each CSV holds every reading the run made, and
    every WrenchStamped received (decoded by rosbags' CDR over its own definitions) is a
    CSV row's force with the row's frame time shifted by one offset."""
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    domain = 9
    router = _start_router(endpoint)
    hands = ("left_hand", "right_hand")
    lock = threading.Lock()
    samples: list[tuple[float, str, bytes]] = []
    tokens: dict[str, str] = {}
    tap = open_client(endpoint)

    def on_sample(s) -> None:
        with lock:
            samples.append((time.monotonic(), str(s.key_expr), s.payload.to_bytes()))

    def on_token(s) -> None:
        with lock:
            tokens[str(s.key_expr)] = str(s.kind)

    tap.declare_subscriber(f"{domain}/**", on_sample)
    tap.liveliness().declare_subscriber(f"@ros2_lv/{domain}/**", on_token, history=True)
    runs: dict[str, subprocess.Popen] = {}
    env = {**os.environ, "ROS_DOMAIN_ID": str(domain), "PYTHONPATH": str(REPO)}
    try:
        for hand in hands:
            scene = tmp_path / f"{hand}.toml"
            scene.write_text(textwrap.dedent(f"""
                [[sensor]]
                name = "{hand}"
                source = "virtual"
                n_grasps = 40
                [[output]]
                kind = "csv"
                path = "{hand}.csv"
                [[output]]
                kind = "zenoh"
                endpoint = "{endpoint}"
                namespace = "/{hand}"
            """))
            runs[hand] = subprocess.Popen([sys.executable, "-m", "tactile_force.edge.cli", "run", "--scene",
                                           str(scene)], cwd=tmp_path, env=env, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.PIPE, text=True)

        def arrived(hand: str, after: float = 0.0) -> int:
            with lock:
                return sum(1 for t, k, _ in samples if t > after and k.startswith(f"{domain}/{hand}/tactile/force/"))

        assert wait_for(lambda: all(arrived(h) >= 30 for h in hands), 120), \
            {h: (arrived(h), r.poll()) for h, r in runs.items()}
        with lock:
            live = {k for k, v in tokens.items() if v == "SampleKind.PUT"}
        for hand in hands:
            assert any(k.endswith(f"/NN/%/%{hand}/tactile_force") for k in live), live
            for sfx, t in (("", WRENCH_STAMPED), ("%diagnostics", DIAGNOSTIC_ARRAY), ("%interval", VECTOR3_STAMPED)):
                assert any(f"/MP/%/%{hand}/tactile_force/%{hand}%tactile%force{sfx}/{ros2_to_dds_type(t)}/"
                           f"{rihs01(t)}/" in k for k in live), (hand, t)

        router.kill()
        router.wait()
        time.sleep(1.0)  # readings made now reach no one; the runs go on
        router = _start_router(endpoint)
        back = time.monotonic()
        resumed = wait_for(lambda: all(arrived(h, back) > 0 for h in hands), 2.0)
        assert resumed, f"not published within 2 s of the router's return: { {h: arrived(h, back) for h in hands} }"
        with lock:
            first = {h: min(t for t, k, _ in samples if t > back and k.startswith(f"{domain}/{h}/")) - back
                     for h in hands}
        print("\npublished again after the router's return (s):", {h: round(v, 3) for h, v in first.items()})
        assert all(r.poll() is None for r in runs.values())
        time.sleep(0.5)
        for r in runs.values():
            r.send_signal(signal.SIGINT)
        errs = {h: r.communicate(timeout=60)[1] for h, r in runs.items()}
        for hand, r in runs.items():
            assert r.returncode == 130, errs[hand]
            assert "outputs closed" in errs[hand]
        assert wait_for(lambda: not [r for r in tap.liveliness().get(f"@ros2_lv/{domain}/**", timeout=1.0) if r.ok],
                        10)
        with lock:
            assert {k for k, v in tokens.items() if v == "SampleKind.PUT"} == set()  # each one undeclared

        store = get_typestore(Stores.ROS2_JAZZY)
        for hand in hands:
            rows = list(csv.DictReader((tmp_path / f"{hand}.csv").open()))
            made = int(errs[hand].split("readings ")[1].split(":")[0])
            assert len(rows) == made and [int(r["frame_index"]) for r in rows] == list(range(made))
            frames = {int(r["timestamp_ns"]): r for r in rows}
            with lock:
                mine = [(k, p) for _, k, p in samples if k.startswith(f"{domain}/{hand}/")]
            offsets = set()
            for k, p in mine:
                if "/diagnostics/" in k:
                    m = store.deserialize_cdr(p, DIAGNOSTIC_ARRAY)
                    index = int({kv.key: kv.value for kv in m.status[0].values}["frame_index"])
                    stamp = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
                    offsets.add(stamp - int(rows[index]["timestamp_ns"]))
            assert len(offsets) == 1
            offset = offsets.pop()
            wrenches = [store.deserialize_cdr(p, WRENCH_STAMPED) for k, p in mine if "WrenchStamped_" in k]
            for m in wrenches:
                row = frames[m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec - offset]
                want = float(row["force_n"]) if row["force_n"] not in ("", "nan") else math.nan
                assert m.header.frame_id == hand
                assert m.wrench.force.z == want or (math.isnan(want) and math.isnan(m.wrench.force.z))
            got = {m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec - offset for m in wrenches}
            lost = [i for i, r in enumerate(rows) if int(r["timestamp_ns"]) not in got]
            # one outage: the readings missing here are one unbroken run of frames
            assert lost == list(range(lost[0], lost[-1] + 1)) if lost else True, lost
            print(f"\n{hand}: {len(rows)} readings in the CSV, {len(wrenches)} WrenchStamped received, "
                  f"{len(lost)} missing (frames {lost[0] if lost else '-'}..{lost[-1] if lost else '-'}: "
                  "the router's outage)")
    finally:
        for r in runs.values():
            if r.poll() is None:
                r.kill()
                r.communicate()
        tap.close()
        router.kill()
        router.wait()


# -- scene and flags -------------------------------------------------------------------------------
def test_scene_and_flags():
    scene = scene_from_flags("virtual", zenoh={"endpoint": "tcp/10.0.0.2:7447", "namespace": "/left_hand",
                                               "mode": "peer", "retry": True})
    (o,) = [o for o in scene.outputs if o.kind == "zenoh"]
    assert (o.topic, o.endpoint, o.mode, o.namespace, o.node, o.retry) == (
        "/left_hand/tactile/force", "tcp/10.0.0.2:7447", "peer", "/left_hand", "tactile_force", True)
    text = scene_to_toml(scene)
    assert 'kind = "zenoh"' in text and 'endpoint = "tcp/10.0.0.2:7447"' in text and "retry = true" in text
    absolute = scene_from_flags("virtual", zenoh={"topic": "/abs/force", "namespace": "/x"})
    assert absolute.outputs[-1].topic == "/abs/force"
    for bad, match in (({"endpoint": "localhost:7447"}, "PROTOCOL/ADDRESS"), ({"namespace": "left"}, "namespace"),
                       ({"node": "9lives"}, "node name"), ({"mode": "router"}, "mode")):
        with pytest.raises(SceneError, match=match):
            scene_from_flags("virtual", zenoh=bad)
    with pytest.raises(SceneError, match="zenoh"):
        from tactile_force.edge.scene import parse_scene

        parse_scene({"sensor": [{"source": "virtual"}], "output": [{"kind": "stdout", "namespace": "/x"}]}, None,
                     Path.cwd())
