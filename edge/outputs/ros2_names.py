"""ROS 2 topic names and the ROS time base of messages (no DDS dependency).

A ROS 2 topic '/tactile/force' travels on the DDS topic 'rt/tactile/force'. Frames are
stamped on the monotonic clock (ns); a ROS 2 header carries ROS time, by default the
system wall clock: :class:`StampClock` adds the wall - monotonic offset taken once, so
every message of a run shares one time base.
"""

from __future__ import annotations

import re
import time

from ..errors import SceneError

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*\Z")


def ros_topic(name: str, what: str = "ROS 2 topic") -> str:
    """A ROS 2 topic name made absolute ('tactile/force' -> '/tactile/force').

    ROS 2's rules for a name (rcl's topic name validation): tokens of letters, digits and '_',
    none starting with a digit, separated by single '/', no '/' at the end, no white space
    anywhere. Raises SceneError (a ValueError) naming ``what`` otherwise; a private name
    ('~/force') is refused here, naming where it is supported (the Zenoh output, which has a node
    to expand it: :func:`~tactile_force.edge.outputs.zenoh_topic.resolve_topic`).
    """
    if not isinstance(name, str) or not name.strip("/"):
        raise SceneError(f"{what} {name!r}: empty; expected a name such as /tactile/force")
    if name.startswith("~"):
        raise SceneError(f"{what} {name!r}: a private name ('~/...') needs a node to expand it; only the Zenoh "
                         "output has one (its topic may be '~/force'); give a relative or absolute name here")
    body = name[1:] if name.startswith("/") else name
    tokens = body.split("/")
    bad = [t for t in tokens if not _TOKEN.match(t)]
    if bad:
        part = "an empty part ('//' or a '/' at the end)" if "" in bad else repr(bad[0])
        raise SceneError(f"{what} {name!r}: not a valid ROS 2 name (expected tokens of letters, digits and '_', "
                         f"not starting with a digit, separated by single '/'; bad part: {part})")
    return "/" + "/".join(tokens)


def dds_topic(name: str) -> str:
    """The DDS topic a ROS 2 topic travels on: '/tactile/force' -> 'rt/tactile/force'."""
    return "rt" + ros_topic(name)


class StampClock:
    """Monotonic frame time (ns) -> ROS time (ns since the epoch) by one fixed offset.

    offset_ns: added to every timestamp; default the wall - monotonic offset now.
    """

    def __init__(self, offset_ns: int | None = None) -> None:
        self.offset_ns = time.time_ns() - time.monotonic_ns() if offset_ns is None else int(offset_ns)

    def ros_ns(self, monotonic_ns: int) -> int:
        """ROS time in ns since the epoch."""
        return int(monotonic_ns) + self.offset_ns

    def sec_nanosec(self, monotonic_ns: int) -> tuple[int, int]:
        """(sec, nanosec) of builtin_interfaces/Time."""
        return divmod(self.ros_ns(monotonic_ns), 1_000_000_000)
