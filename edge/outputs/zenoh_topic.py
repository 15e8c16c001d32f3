"""Publish readings to a ROS 2 graph on rmw_zenoh, through a Zenoh router (the ``zenoh`` extra).

The same topics, types and CDR bytes as the DDS output (:mod:`.ros2_topic`): per reading a
``geometry_msgs/msg/WrenchStamped`` on the topic, a ``diagnostic_msgs/msg/DiagnosticArray``
on ``topic + '/diagnostics'`` and the interval as ``geometry_msgs/msg/Vector3Stamped`` on
``topic + '/interval'``, sent on rmw_zenoh's key expressions with its attachment, and the node
and its publishers announced by rmw_zenoh's liveliness tokens (:mod:`.zenoh_wire`), so
``ros2 node list`` / ``ros2 topic list`` on a host with ``RMW_IMPLEMENTATION=rmw_zenoh_cpp``
show them and its subscribers receive them. No ROS installation is needed here.

Network: client mode to a router (``tcp/localhost:7447`` by default, what ``ros2 run
rmw_zenoh_cpp rmw_zenohd`` listens on) or peer mode (listening on ``tcp/localhost:0``, as
rmw_zenoh's nodes do, and connecting to the router); multicast scouting off. A router that
goes away and comes back is reconnected to by Zenoh (tried every 0.1 s, backing off to 1 s):
readings published meanwhile are lost on this output only; the liveliness tokens come back
with the connection.
"""

from __future__ import annotations

import json
import re
import threading
import time
from dataclasses import dataclass
from typing import Any

from ..errors import SceneError, require
from ..reading import ForceReading
from .ros2_names import StampClock, ros_topic
from .ros2_topic import QosProfile, Ros2Topics, domain_from_env
from .zenoh_wire import NodeName, WireQos, attachment, new_gid, topic_key

#: Where ``rmw_zenohd`` (and ``zenohd``) listen by default.
DEFAULT_ENDPOINT = "tcp/localhost:7447"
MODES = ("client", "peer")
DEFAULT_TOPIC = "tactile/force"
DEFAULT_NODE = "tactile_force"
_ENDPOINT = re.compile(r"^[a-z][a-z0-9-]*/\S+\Z")
_NODE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\Z")
#: Zenoh's reconnection to a lost router: first try after 0.1 s, doubling to 1 s.
_RETRY = {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 2}


def resolve_topic(topic: str, namespace: str = "/", node: str = DEFAULT_NODE) -> str:
    """A topic as ROS 2 resolves it for ``node`` in ``namespace``: absolute ('/x') as is, relative
    ('x') under the namespace, private ('~' or '~/x') under the namespace and the node's name;
    SceneError naming the bad name (ROS 2's rules, :func:`~.ros2_names.ros_topic`)."""
    ns = check_namespace(namespace).rstrip("/")
    if isinstance(topic, str) and topic.startswith("~"):
        if topic != "~" and not topic.startswith("~/"):
            raise SceneError(f"Zenoh topic {topic!r}: a private name is '~' or '~/NAME' (ROS 2's rules)")
        return ros_topic(f"{ns}/{check_node_name(node)}{topic[1:]}", "Zenoh topic")
    if isinstance(topic, str) and topic.startswith("/"):
        return ros_topic(topic, "Zenoh topic")
    ros_topic(topic, "Zenoh topic")  # the name's own check
    return ros_topic(ns + "/" + topic, "Zenoh topic")


def check_namespace(namespace: str) -> str:
    """'/' or an absolute ROS 2 namespace ('/left_hand'; rcl's rules: no '//', no '/' at the end, no
    white space); SceneError otherwise."""
    if namespace == "/":
        return namespace
    if not isinstance(namespace, str) or not namespace.startswith("/"):
        raise SceneError(f"Zenoh namespace {namespace!r}: expected '/' or an absolute name such as '/left_hand'")
    return ros_topic(namespace, "Zenoh namespace")


def check_node_name(name: str) -> str:
    """A ROS 2 node name (rmw's rules): letters, digits and '_', not starting with a digit, at most
    255 characters, no white space."""
    if not isinstance(name, str) or not _NODE.match(name) or len(name) > 255:
        raise SceneError(f"Zenoh node name {name!r}: expected letters, digits and '_', not starting with a digit "
                         "(ROS 2's rules for a node name)")
    return name


#: Zenoh's link protocols; those of an IP link need HOST:PORT with a port 1..65535
_IP_PROTOCOLS = ("tcp", "udp", "tls", "quic", "ws")
_OTHER_PROTOCOLS = ("unixsock-stream", "unixpipe", "serial", "vsock")
_HOST_PORT = re.compile(r"^(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):(\d{1,5})\Z")


def check_endpoint(endpoint: str) -> str:
    """A Zenoh locator to connect to, such as 'tcp/192.168.1.10:7447' (Zenoh's rules: a known
    protocol; for an IP link, HOST:PORT with the port in 1..65535; no white space); SceneError
    naming what is wrong otherwise."""
    bad = f"Zenoh endpoint {endpoint!r}: "
    if not isinstance(endpoint, str) or not _ENDPOINT.match(endpoint):
        raise SceneError(bad + f"expected PROTOCOL/ADDRESS such as {DEFAULT_ENDPOINT!r}")
    proto, _, rest = endpoint.partition("/")
    address = rest.split("?", 1)[0].split("#", 1)[0]
    if proto not in _IP_PROTOCOLS + _OTHER_PROTOCOLS:
        raise SceneError(bad + f"unknown protocol {proto!r}; expected one of {', '.join(_IP_PROTOCOLS)} "
                         f"(or {', '.join(_OTHER_PROTOCOLS)})")
    if proto in _IP_PROTOCOLS:
        m = _HOST_PORT.match(address)
        if m is None:
            raise SceneError(bad + f"expected HOST:PORT after '{proto}/', such as {DEFAULT_ENDPOINT!r}")
        if not 1 <= int(m.group(1)) <= 65535:
            raise SceneError(bad + f"port {int(m.group(1))} is outside 1..65535")
    return endpoint


def session_config(endpoint: str, mode: str, connect_timeout_s: float) -> Any:
    """The Zenoh configuration of the publishing session: ``mode`` ('client' or 'peer')
    connecting to ``endpoint`` (giving up after ``connect_timeout_s`` when opened), multicast
    scouting off, a peer listening on the loopback only."""
    import zenoh

    if mode not in MODES:
        raise SceneError(f"Zenoh mode {mode!r}: expected one of {list(MODES)}")
    conf = zenoh.Config()
    try:
        conf.insert_json5("mode", json.dumps(mode))
        conf.insert_json5("connect/endpoints", json.dumps([check_endpoint(endpoint)]))
        conf.insert_json5("connect/timeout_ms", str(max(1, round(connect_timeout_s * 1000))))
        conf.insert_json5("connect/exit_on_failure", "true")
        conf.insert_json5("connect/retry", json.dumps(_RETRY))
        conf.insert_json5("scouting/multicast/enabled", "false")
        if mode == "peer":
            conf.insert_json5("listen/endpoints", json.dumps(["tcp/localhost:0"]))
    except zenoh.ZError as exc:
        raise SceneError(f"Zenoh endpoint {endpoint!r}: {exc}") from None
    return conf


@dataclass(slots=True)
class _Writer:
    """One declared publisher: its Zenoh publisher, GID and last sequence number."""

    publisher: Any
    token: Any
    gid: bytes
    sequence: int = 0


class ZenohPublisher:
    """A reading sink that publishes as a ROS 2 node on rmw_zenoh would.

    Parameters
    ----------
    topic : str
        Topic of the WrenchStamped messages; relative names ('tactile/force', the default)
        are resolved under ``namespace``.
    namespace : str
        The node's namespace, '/' (default) or e.g. '/left_hand' (one per runtime of a fleet).
    node : str
        The node's name (default 'tactile_force').
    endpoint : str, optional
        The Zenoh locator to connect to; default 'tcp/localhost:7447'.
    mode : str
        'client' (default: everything through the router) or 'peer'.
    domain_id : int, optional
        ROS domain; default ``ROS_DOMAIN_ID`` or 0.
    qos : str
        'sensor_data' (default: best effort, keep last 5, volatile) or 'reliable' (keep last 10).
    diagnostics, interval : bool
        Also publish the DiagnosticArray / the interval (as the DDS output).
    stamp_clock : StampClock, optional
        Monotonic frame time -> ROS time; default the wall - monotonic offset at start.
    retry : bool
        When nothing answers at ``endpoint``: False (default) raises SceneError naming it;
        True returns at once and keeps trying in the background (every ``retry_period_s``);
        readings written meanwhile are counted in ``dropped`` and reach no one (the other
        outputs of a run keep theirs).
    connect_timeout_s : float
        How long one attempt to reach the endpoint waits (s).

    Raises MissingExtraError naming the ``zenoh`` extra when eclipse-zenoh (or cyclonedds,
    which encodes the CDR) is missing.
    """

    def __init__(self, topic: str = DEFAULT_TOPIC, *, namespace: str = "/", node: str = DEFAULT_NODE,
                 endpoint: str | None = None, mode: str = "client", domain_id: int | None = None,
                 qos: str = "sensor_data", diagnostics: bool = True, interval: bool = True,
                 stamp_clock: StampClock | None = None, retry: bool = False, connect_timeout_s: float = 3.0,
                 retry_period_s: float = 0.5) -> None:
        from ..checks import expect

        expect(topic, str, "ZenohPublisher.topic", nonempty=True)
        expect(namespace, str, "ZenohPublisher.namespace")
        expect(node, str, "ZenohPublisher.node", nonempty=True)
        expect(endpoint, str | None, "ZenohPublisher.endpoint")
        expect(mode, str, "ZenohPublisher.mode")
        if mode not in MODES:
            from ..errors import OptionsError

            raise OptionsError(f"ZenohPublisher.mode={mode!r}: expected one of {', '.join(MODES)}")
        expect(domain_id, int | None, "ZenohPublisher.domain_id", ge=0, le=232)
        expect(qos, str, "ZenohPublisher.qos")
        for flag, value in (("diagnostics", diagnostics), ("interval", interval), ("retry", retry)):
            expect(value, bool, f"ZenohPublisher.{flag}")
        expect(stamp_clock, StampClock | None, "ZenohPublisher.stamp_clock", "a StampClock or None (the default)")
        expect(connect_timeout_s, float, "ZenohPublisher.connect_timeout_s", "a number of seconds > 0", gt=0)
        expect(retry_period_s, float, "ZenohPublisher.retry_period_s", "a number of seconds > 0", gt=0)
        self.namespace = check_namespace(namespace)
        self.node = check_node_name(node)
        force = resolve_topic(topic, self.namespace, self.node)
        self.topics = Ros2Topics(force, force + "/diagnostics" if diagnostics else None,
                                 force + "/interval" if interval else None)
        self.endpoint = check_endpoint(endpoint if endpoint is not None else DEFAULT_ENDPOINT)
        self.mode = mode
        self.qos = QosProfile.parse(qos)
        self.domain_id = domain_from_env(domain_id)
        self.clock = stamp_clock or StampClock()
        self.retry_period_s = float(retry_period_s)
        self.published = 0
        self.dropped = 0
        self.zid: str | None = None
        self.last_error: str | None = None
        zenoh = require("zenoh", "zenoh", "Zenoh output")
        require("cyclonedds", "zenoh", "Zenoh output (CDR encoding)")
        from .ros2_messages import DIAGNOSTIC_ARRAY, VECTOR3_STAMPED, WRENCH_STAMPED, reading_payloads
        from .ros2_type_hash import rihs01

        self._payloads = reading_payloads
        self._types = {t: (ty, rihs01(ty)) for t, ty in ((self.topics.force, WRENCH_STAMPED),
                                                          (self.topics.diagnostics, DIAGNOSTIC_ARRAY),
                                                          (self.topics.interval, VECTOR3_STAMPED)) if t}
        self._zenoh = zenoh
        self._config = session_config(self.endpoint, mode, connect_timeout_s)
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._closed = False
        self._session: Any = None
        self._node_token: Any = None
        self._writers: dict[str, _Writer] = {}
        self._thread: threading.Thread | None = None
        if not retry:
            try:
                session = zenoh.open(self._config)
            except zenoh.ZError as exc:
                raise SceneError(self._unreachable(exc) + "; start a router there (ros2 run rmw_zenoh_cpp rmw_zenohd, "
                                 "or zenohd), or pass --zenoh-retry (scene: retry = true) to keep the run's other "
                                 "outputs going while it is tried again") from None
            self._declare(session)
        else:
            self._thread = threading.Thread(target=self._connect, name="zenoh-connect", daemon=True)
            self._thread.start()

    def _unreachable(self, exc: Exception) -> str:
        why = re.sub(r"\s+at /\S+\.rs:\d+\.?", "", str(exc)).strip()  # no Rust source path
        return f"Zenoh output ({self.mode} mode): no Zenoh router answers at {self.endpoint} ({why})"

    @property
    def connected(self) -> bool:
        """Whether the session is open and the node declared (it may still be reconnecting)."""
        return bool(self._writers)

    def _connect(self) -> None:
        while not self._stop.is_set():
            try:
                session = self._zenoh.open(self._config)
            except self._zenoh.ZError as exc:
                self.last_error = self._unreachable(exc)
                self._stop.wait(self.retry_period_s)
                continue
            with self._lock:
                if self._closed:
                    session.close()
                    return
                self._declare(session)
            return

    def _declare(self, session: Any) -> None:
        """The node's token, then per topic its publisher and token (rmw_zenoh's order)."""
        zenoh = self._zenoh
        self._session = session
        self.zid = str(session.zid())
        name = NodeName(self.domain_id, self.namespace, self.node, self.zid)
        self._node_token = session.liveliness().declare_token(name.node_token())
        best_effort = self.qos is QosProfile.SENSOR_DATA
        wire_qos = WireQos(reliable=not best_effort, depth=5 if best_effort else 10)
        reliability = zenoh.Reliability.BEST_EFFORT if best_effort else zenoh.Reliability.RELIABLE
        writers = {}
        for entity_id, (topic, (ros_type, type_hash)) in enumerate(self._types.items(), start=1):
            pub = session.declare_publisher(topic_key(self.domain_id, topic, ros_type, type_hash),
                                            congestion_control=zenoh.CongestionControl.DROP, reliability=reliability)
            token = session.liveliness().declare_token(
                name.publisher_token(entity_id, topic, ros_type, type_hash, wire_qos))
            writers[topic] = _Writer(pub, token, new_gid())
        self._writers = writers  # one assignment: write() sees all of them or none

    def write(self, reading: ForceReading) -> None:
        """Publish one reading (WrenchStamped, DiagnosticArray, interval), or count it in
        ``dropped`` while the first connection is still being tried."""
        if self._closed:
            raise RuntimeError(f"Zenoh publisher on {self.topics.force}: write after close")
        writers = self._writers
        if not writers:
            self.dropped += 1
            return
        now = time.time_ns()
        for topic, _, data in self._payloads(reading, self.clock, self.topics.force):
            w = writers.get(topic)
            if w is not None:
                w.sequence += 1
                w.publisher.put(data, attachment=attachment(w.sequence, now, w.gid))
        self.published += 1

    def close(self) -> None:
        """Undeclare the publishers' and the node's liveliness tokens (the ROS graph sees
        them leave), the publishers, and close the session; safe to call twice."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._stop.set()
            writers, self._writers = self._writers, {}
            for w in writers.values():
                w.token.undeclare()
                w.publisher.undeclare()
            if self._node_token is not None:
                self._node_token.undeclare()
                self._node_token = None
            session, self._session = self._session, None
            if session is not None:
                session.close()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def __enter__(self) -> ZenohPublisher:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
