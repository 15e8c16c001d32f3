"""rmw_zenoh's wire format: key expressions, liveliness tokens, QoS text and attachments.

What a ROS 2 node on ``rmw_zenoh_cpp`` puts on the Zenoh network (its ``docs/design.md``),
written out so that this package publishes as such a node does, without ROS (no Zenoh
import here; :mod:`.zenoh_topic` sends it):

- a topic's samples go on ``<domain_id>/<topic without its leading '/'>/<DDS type name>/
  <RIHS01 type hash>``, e.g. ``0/tactile/force/geometry_msgs::msg::dds_::WrenchStamped_/RIHS01_8dc3...``;
  the payload is the message in CDR (little-endian, the 4-byte encapsulation header first);
- every sample carries an attachment: the publisher's sequence number (int64, from 1), the
  source timestamp (int64, ns since the epoch), then the 16-byte publisher GID as a Zenoh
  serialised sequence (its length 16 as one LEB128 byte, 0x10, then the bytes): 33 bytes;
- the ROS graph (``ros2 node list``, ``ros2 topic list``) is made of liveliness tokens:
  ``@ros2_lv/<domain>/<session zid>/<node id>/<node id>/NN/<enclave>/<namespace>/<node name>``
  for a node and ``@ros2_lv/<domain>/<zid>/<node id>/<entity id>/MP/<enclave>/<namespace>/
  <node name>/<topic>/<DDS type>/<type hash>/<QoS>`` for each publisher; names are
  "mangled" ('/' -> '%', the root namespace and the empty enclave are '%');
- the QoS in a token is ``<reliability>:<durability>:<history kind>,<depth>:<deadline
  s,ns>:<lifespan s,ns>:<liveliness kind,s,ns>`` with rmw's enum numbers (reliable 1,
  best effort 2; transient local 1, volatile 2; keep last 1, keep all 2), a field left empty
  when it is the default (reliable, volatile, keep last, infinite durations, automatic).
"""

from __future__ import annotations

import os
import struct
from dataclasses import dataclass

from .ros2_names import ros_topic

LIVELINESS_PREFIX = "@ros2_lv"
NODE_KIND = "NN"
PUBLISHER_KIND = "MP"
GID_SIZE = 16


def dds_type_name(ros_type: str) -> str:
    """'geometry_msgs/msg/WrenchStamped' -> 'geometry_msgs::msg::dds_::WrenchStamped_'."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def mangle(name: str) -> str:
    """A ROS name in a liveliness token: '/' -> '%'; the root '/' (or '') is '%'."""
    return "%" if name in ("", "/") else name.replace("/", "%")


def topic_key(domain_id: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The data key expression of an absolute ROS 2 topic."""
    return f"{domain_id}/{ros_topic(topic).lstrip('/')}/{dds_type_name(ros_type)}/{type_hash}"


@dataclass(frozen=True, slots=True)
class WireQos:
    """The QoS a publisher declares: reliable or best effort, keep last ``depth``, volatile."""

    reliable: bool
    depth: int

    def token(self) -> str:
        """The QoS text of a liveliness token (defaults left empty, the depth always given)."""
        return f"{'' if self.reliable else 2}::,{self.depth}:,:,:,,"


@dataclass(frozen=True, slots=True)
class NodeName:
    """Where a node sits in the ROS graph: domain, namespace ('/' or '/a/b'), name, its
    Zenoh session's id (hex, as ``str(session.zid())`` prints it) and its entity id."""

    domain_id: int
    namespace: str
    name: str
    zid: str
    node_id: int = 0
    enclave: str = ""

    def _prefix(self, entity_id: int, kind: str) -> str:
        return (f"{LIVELINESS_PREFIX}/{self.domain_id}/{self.zid}/{self.node_id}/{entity_id}/{kind}/"
                f"{mangle(self.enclave)}/{mangle(self.namespace)}/{self.name}")

    def node_token(self) -> str:
        """The node's liveliness key expression (``ros2 node list``)."""
        return self._prefix(self.node_id, NODE_KIND)

    def publisher_token(self, entity_id: int, topic: str, ros_type: str, type_hash: str, qos: WireQos) -> str:
        """A publisher's liveliness key expression (``ros2 topic list``, ``ros2 topic info``)."""
        return (f"{self._prefix(entity_id, PUBLISHER_KIND)}/{mangle(ros_topic(topic))}/{dds_type_name(ros_type)}/"
                f"{type_hash}/{qos.token()}")


def new_gid() -> bytes:
    """A random 16-byte publisher GID."""
    return os.urandom(GID_SIZE)


def attachment(sequence: int, source_timestamp_ns: int, gid: bytes) -> bytes:
    """The attachment of one sample (33 bytes)."""
    if len(gid) != GID_SIZE:
        raise ValueError(f"publisher GID: expected {GID_SIZE} bytes, got {len(gid)}")
    return struct.pack("<qqB", sequence, source_timestamp_ns, GID_SIZE) + gid

