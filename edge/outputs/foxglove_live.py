"""Live view in Foxglove: a Foxglove WebSocket server streaming the readings (the
``foxglove`` extra, ``foxglove-sdk``).

The same topics, types and CDR bytes as the ROS 2 output and the MCAP log
(``/tactile/force`` WrenchStamped, ``/tactile/force/diagnostics`` DiagnosticArray, and
through :meth:`FoxgloveLive.write_frame` the frames and contact masks as
CompressedImage), so one Foxglove layout serves all three. Open Foxglove, "Open
connection", ``ws://127.0.0.1:8765``. The server binds to 127.0.0.1 by default: it is
reachable from this host only (use an SSH tunnel to watch from another machine).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import SceneError, require
from ..reading import ForceReading
from .mcap_log import image_payloads
from .ros2_names import StampClock, ros_topic

DEFAULT_PORT = 8765


class FoxgloveLive:
    """A reading sink that streams to Foxglove over its WebSocket protocol.

    Parameters
    ----------
    host : str
        Address to bind (default 127.0.0.1: this host only).
    port : int
        TCP port (default 8765; 0 picks a free one, see :attr:`port`).
    topic : str
        ROS 2 topic of the readings; diagnostics on ``topic + '/diagnostics'``.
    frames, mask : bool
        Accept frames / contact masks through :meth:`write_frame`.
    stamp_clock : StampClock, optional
        Monotonic frame time -> ROS time; default the wall - monotonic offset at start.
    """

    def __init__(self, *, host: str = "127.0.0.1", port: int = DEFAULT_PORT, topic: str = "/tactile/force",
                 frames: bool = False, mask: bool = False, stamp_clock: StampClock | None = None) -> None:
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise SceneError(f"Foxglove port {port!r}: expected an integer 0..65535")
        self.topic = ros_topic(topic, "Foxglove topic")
        self.namespace = self.topic.rsplit("/", 1)[0]
        self.frames = frames
        self.mask = mask
        self.clock = stamp_clock or StampClock()
        fg = require("foxglove", "foxglove", "the Foxglove live view")
        from . import ros2_messages as msgs

        self._fg = fg
        self._msgs = msgs
        self._context = fg.Context()  # our channels only, not the SDK's global context
        try:
            self._server = fg.start_server(name="tactile-force", host=host, port=port, context=self._context)
        except Exception as exc:  # the SDK raises its own error types for a busy or bad address
            raise SceneError(f"Foxglove server on {host}:{port}: cannot start ({exc})") from None
        self._channels: dict[str, Any] = {}
        self._closed = False

    @property
    def port(self) -> int:
        """The TCP port the server listens on."""
        return int(self._server.port)

    def _channel(self, topic: str, type_name: str) -> Any:
        ch = self._channels.get(topic)
        if ch is None:
            schema = self._fg.Schema(name=type_name, encoding="ros2msg",
                                     data=self._msgs.MSG_DEFINITIONS[type_name].encode())
            ch = self._fg.Channel(topic, schema=schema, message_encoding="cdr", context=self._context)
            self._channels[topic] = ch
        return ch

    def write(self, reading: ForceReading) -> None:
        """Stream one reading (WrenchStamped + DiagnosticArray)."""
        if self._closed:
            raise RuntimeError("Foxglove live view: write after close")
        t = self.clock.ros_ns(reading.timestamp_ns)
        for topic, type_name, data in self._msgs.reading_payloads(reading, self.clock, self.topic):
            self._channel(topic, type_name).log(data, log_time=t)

    def write_frame(self, sensor: str, timestamp_ns: int, frame_bgr: np.ndarray | None,
                    mask: np.ndarray | None = None) -> None:
        """Stream the frame (HxWx3 uint8 BGR, JPEG) and/or contact mask (HxW, PNG), each
        only when enabled at construction."""
        if self._closed:
            raise RuntimeError("Foxglove live view: write after close")
        t = self.clock.ros_ns(timestamp_ns)
        for topic, type_name, data in image_payloads(self.namespace, sensor, timestamp_ns,
                                                     frame_bgr if self.frames else None,
                                                     mask if self.mask else None, self.clock):
            self._channel(topic, type_name).log(data, log_time=t)

    def close(self) -> None:
        """Stop the server; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        for ch in self._channels.values():
            ch.close()
        self._server.stop()

    def __enter__(self) -> FoxgloveLive:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
