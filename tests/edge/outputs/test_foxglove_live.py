"""Foxglove live view: a real Foxglove WebSocket server on 127.0.0.1 and a real WebSocket
client (the ``websockets`` library) speaking the Foxglove protocol: advertised channels,
subscription, and message frames that decode to the readings."""

from __future__ import annotations

import json
import math
import struct
import subprocess

import numpy as np
import pytest

pytest.importorskip("foxglove", reason="the live view needs foxglove-sdk (the 'foxglove' extra)")
ws_client = pytest.importorskip("websockets.sync.client", reason="the test client needs 'websockets'")

from tactile_force.edge.outputs.foxglove_live import FoxgloveLive  # noqa: E402
from tactile_force.edge.outputs.ros2_messages import (  # noqa: E402
    CompressedImage,
    DiagnosticArray,
    Vector3Stamped,
    WrenchStamped,
)
from tactile_force.edge.outputs.ros2_names import StampClock  # noqa: E402
from tactile_force.edge.reading import Flags, ForceReading, IntervalState  # noqa: E402


def _recv_json(ws, op: str) -> dict:
    for _ in range(10):
        msg = json.loads(ws.recv(timeout=5))
        if msg["op"] == op:
            return msg
    raise AssertionError(f"no {op!r} from the server")


def test_client_on_loopback_receives_readings_and_masks():
    with FoxgloveLive(port=0, mask=True, stamp_clock=StampClock(offset_ns=0)) as live:
        live.write(ForceReading("left", 2_000_000_000, 0, 0.0, Flags.NO_CONTACT))  # advertises the channels
        live.write_frame("left", 2_000_000_000, np.zeros((320, 240, 3), np.uint8), np.eye(320, 240, dtype=bool))
        try:
            ss = subprocess.run(["ss", "-ltnH"], check=False, capture_output=True, text=True, timeout=10).stdout
        except (OSError, subprocess.SubprocessError):
            ss = ""
        listening = [ln.split()[3] for ln in ss.splitlines() if ln.split()[3].endswith(f":{live.port}")]
        assert not ss or listening, f"port {live.port} not listed by ss"
        assert all(addr.startswith("127.0.0.1:") for addr in listening), listening  # this host only
        with ws_client.connect(f"ws://127.0.0.1:{live.port}", subprotocols=["foxglove.sdk.v1"]) as ws:
            _recv_json(ws, "serverInfo")
            adv = {c["topic"]: c for c in _recv_json(ws, "advertise")["channels"]}
            assert set(adv) == {"/tactile/force", "/tactile/force/diagnostics", "/tactile/force/interval",
                                "/tactile/left/contact_mask/compressed"}
            assert (adv["/tactile/force"]["schemaName"], adv["/tactile/force"]["encoding"],
                    adv["/tactile/force"]["schemaEncoding"]) == ("geometry_msgs/msg/WrenchStamped", "cdr", "ros2msg")
            subs = {1: "/tactile/force", 2: "/tactile/force/diagnostics", 3: "/tactile/left/contact_mask/compressed",
                    4: "/tactile/force/interval"}
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": adv[t]["id"]}
                                                                      for i, t in subs.items()]}))
            got: dict[str, list] = {t: [] for t in subs.values()}
            for _ in range(50):  # the subscription takes effect asynchronously: keep writing until data flows
                live.write(ForceReading("left", 3_000_000_000, 1, 6.5, Flags.SATURATED, force_low_n=5.25,
                                        force_high_n=math.inf, interval=IntervalState.OPEN_ABOVE))
                live.write_frame("left", 3_000_000_000, None, np.eye(320, 240, dtype=np.uint8))
                try:
                    while True:
                        frame = ws.recv(timeout=0.1)
                        if isinstance(frame, bytes) and frame[0] == 0x01:  # messageData
                            sub, log_time = struct.unpack_from("<IQ", frame, 1)
                            got[subs[sub]].append((log_time, frame[13:]))
                except TimeoutError:
                    pass
                if all(got.values()):
                    break
    assert all(got.values()), {t: len(v) for t, v in got.items()}
    log_time, data = got["/tactile/force"][0]
    w = WrenchStamped.deserialize(data)
    assert log_time == 3_000_000_000 and w.wrench.force.z == 6.5 and w.header.frame_id == "left"
    d = DiagnosticArray.deserialize(got["/tactile/force/diagnostics"][0][1])
    assert d.status[0].level == 1 and d.status[0].message == "saturated"
    kv = {v.key: v.value for v in d.status[0].values}
    assert (kv["force_low_n"], kv["force_high_n"], kv["interval"]) == ("5.25", "inf", "open_above")
    iv = Vector3Stamped.deserialize(got["/tactile/force/interval"][0][1])
    assert (iv.vector.x, iv.vector.y, iv.vector.z) == (5.25, 6.5, math.inf) and iv.header.frame_id == "left"
    img = CompressedImage.deserialize(got["/tactile/left/contact_mask/compressed"][0][1])
    import cv2

    mask = cv2.imdecode(np.frombuffer(bytes(img.data), np.uint8), cv2.IMREAD_UNCHANGED)
    assert img.format == "png" and np.array_equal(mask > 0, np.eye(320, 240, dtype=bool))
    assert not math.isnan(w.wrench.force.z)


def test_bad_port_and_write_after_close():
    with pytest.raises(ValueError, match="port 70000"):
        FoxgloveLive(port=70000)
    live = FoxgloveLive(port=0)
    live.close()
    live.close()
    with pytest.raises(RuntimeError, match="after close"):
        live.write(ForceReading("left", 0, 0, 1.0))
