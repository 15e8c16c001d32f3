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

_TOKEN = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def ros_topic(name: str, what: str = "ROS 2 topic") -> str:
    """A ROS 2 topic name made absolute ('tactile/force' -> '/tactile/force').

    Raises SceneError (a ValueError) naming ``what`` when it is not a valid ROS 2 name
    (tokens of letters, digits and '_' not starting with a digit, separated by single '/').
    """
    if not isinstance(name, str) or not name.strip().strip("/"):
        raise SceneError(f"{what} {name!r}: empty; expected a name such as /tactile/force")
    tokens = name.strip().lstrip("/").split("/")
    bad = [t for t in tokens if not _TOKEN.match(t)]
    if bad:
        raise SceneError(f"{what} {name!r}: not a valid ROS 2 name (expected tokens of letters, digits and '_', "
                         f"not starting with a digit, separated by single '/'; bad part: {bad[0]!r})")
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
