"""MCAP output: real files read back with the mcap reader (and, when installed, decoded by
mcap-ros2-support's own CDR decoder from the file's ros2msg schemas); a writer killed with
SIGKILL mid-run leaves every flushed reading readable."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import textwrap
import time
from collections import Counter

import numpy as np
import pytest

pytest.importorskip("mcap", reason="MCAP output needs the 'mcap' extra")
pytest.importorskip("cyclonedds", reason="MCAP output serialises CDR with cyclonedds (the 'mcap' extra)")

from mcap.reader import make_reader  # noqa: E402
from tactile_force.edge.outputs.mcap_log import McapWriter, read_messages  # noqa: E402
from tactile_force.edge.outputs.ros2_messages import (  # noqa: E402
    CompressedImage,
    DiagnosticArray,
    WrenchStamped,
)
from tactile_force.edge.outputs.ros2_names import StampClock  # noqa: E402
from tactile_force.edge.reading import Flags, ForceReading, StageLatency  # noqa: E402


def _readings() -> list[ForceReading]:
    out = []
    for i in range(6):
        sensor = "left" if i % 2 == 0 else "right"
        flags = Flags.NO_CONTACT if i == 0 else (Flags.INVALID_INPUT if i == 3 else Flags.NONE)
        force = 0.0 if i == 0 else (math.nan if i == 3 else 1.25 * i)
        out.append(ForceReading(sensor, 5_000_000_000 + i * 16_666_667, i, force, flags,
                                StageLatency(0.1, 0.2, 0.0, 1.0 + i, 1.5 + i)))
    return out


def test_readings_frames_and_masks_read_back(tmp_path, portraits):
    path = tmp_path / "run" / "log.mcap"
    readings = _readings()
    with McapWriter(path, frames=True, mask=True, stamp_clock=StampClock(offset_ns=1_000_000_000)) as w:
        for r, frame in zip(readings, portraits * 2):
            mask = frame[:, :, 1] > 128
            w.write_frame(r.sensor, r.timestamp_ns, frame, mask)
            w.write(r)
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert reader.get_header().profile == "ros2"
        counts = {summary.channels[c].topic: n for c, n in summary.statistics.channel_message_counts.items()}
        schemas = {summary.channels[c].topic: (summary.schemas[summary.channels[c].schema_id].name,
                                                summary.schemas[summary.channels[c].schema_id].encoding,
                                                summary.channels[c].message_encoding) for c in summary.channels}
        assert summary.statistics.chunk_count >= len(readings)  # one chunk closed per reading
    assert counts == {"/tactile/force": 6, "/tactile/force/diagnostics": 6, "/tactile/force/interval": 6,
                      "/tactile/left/image/compressed": 3,
                      "/tactile/right/image/compressed": 3, "/tactile/left/contact_mask/compressed": 3,
                      "/tactile/right/contact_mask/compressed": 3}
    assert schemas["/tactile/force"] == ("geometry_msgs/msg/WrenchStamped", "ros2msg", "cdr")
    assert schemas["/tactile/force/diagnostics"][0] == "diagnostic_msgs/msg/DiagnosticArray"
    assert schemas["/tactile/left/image/compressed"][0] == "sensor_msgs/msg/CompressedImage"

    msgs = list(read_messages(path))
    wrenches = [WrenchStamped.deserialize(m.data) for m in msgs if m.topic == "/tactile/force"]
    diags = [DiagnosticArray.deserialize(m.data) for m in msgs if m.topic == "/tactile/force/diagnostics"]
    for r, w_, d in zip(readings, wrenches, diags):
        ns = r.timestamp_ns + 1_000_000_000
        assert (w_.header.stamp.sec, w_.header.stamp.nanosec) == divmod(ns, 10**9)
        assert w_.header.frame_id == r.sensor
        assert (math.isnan(r.force_n) and math.isnan(w_.wrench.force.z)) or w_.wrench.force.z == r.force_n
        assert d.status[0].message.split(":")[0] == (",".join(r.flags.names()) or "ok")
        assert float({kv.key: kv.value for kv in d.status[0].values}["total_ms"]) == r.latency.total_ms
    assert [m.log_time_ns for m in msgs if m.topic == "/tactile/force"] == [r.timestamp_ns + 10**9 for r in readings]

    images = [(m.topic, CompressedImage.deserialize(m.data)) for m in msgs if m.topic.endswith("/compressed")]
    import cv2

    topic, first = images[0]
    assert topic == "/tactile/left/image/compressed" and first.format == "jpeg"
    decoded = cv2.imdecode(np.frombuffer(bytes(first.data), np.uint8), cv2.IMREAD_COLOR)
    assert decoded.shape == portraits[0].shape
    assert np.abs(decoded.astype(int) - portraits[0].astype(int)).mean() < 3.0  # JPEG q90 of the real frame
    _, mask_msg = images[1]
    assert mask_msg.format == "png"
    mask_img = cv2.imdecode(np.frombuffer(bytes(mask_msg.data), np.uint8), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(mask_img > 0, portraits[0][:, :, 1] > 128)  # PNG: lossless


def test_ros2_decoder_reads_the_schemas(tmp_path):
    """mcap-ros2-support parses our ros2msg schema text and decodes our CDR independently."""
    decoder = pytest.importorskip("mcap_ros2.decoder", reason="mcap-ros2-support not installed")
    path = tmp_path / "x.mcap"
    with McapWriter(path, stamp_clock=StampClock(offset_ns=0)) as w:
        for r in _readings():
            w.write(r)
    with open(path, "rb") as fh:
        got = [(c.topic, m) for _, c, _, m in make_reader(fh, decoder_factories=[decoder.DecoderFactory()])
               .iter_decoded_messages()]
    forces = [m.wrench.force.z for t, m in got if t == "/tactile/force"]
    assert forces[:3] == [0.0, 1.25, 2.5] and math.isnan(forces[3])
    diag = [m for t, m in got if t == "/tactile/force/diagnostics"][3]
    assert diag.status[0].level == 2 and diag.status[0].hardware_id == "right"
    assert diag.header.stamp.sec == 5


def test_frames_off_by_default_and_bad_input(tmp_path):
    path = tmp_path / "plain.mcap"
    with McapWriter(path) as w:
        w.write_frame("left", 1, np.zeros((320, 240, 3), np.uint8), np.zeros((320, 240), bool))  # not enabled
        w.write(_readings()[0])
    assert Counter(m.topic for m in read_messages(path)) == {"/tactile/force": 1, "/tactile/force/diagnostics": 1,
                                                             "/tactile/force/interval": 1}
    with McapWriter(tmp_path / "bad.mcap", frames=True, mask=True) as w:
        with pytest.raises(ValueError, match="HxWx3 uint8"):
            w.write_frame("left", 1, np.zeros((320, 240), np.uint8))
        with pytest.raises(ValueError, match="HxW bool or uint8"):
            w.write_frame("left", 1, None, np.zeros((320, 240, 3), np.float32))
        with pytest.raises(ValueError, match="sensor 'left-1'"):
            w.write_frame("left-1", 1, np.zeros((320, 240, 3), np.uint8))
    with pytest.raises(ValueError, match="flush_every"):
        McapWriter(tmp_path / "x.mcap", flush_every=0)
    with pytest.raises(ValueError, match="MCAP topic"):
        McapWriter(tmp_path / "y.mcap", topic="/bad topic")
    w = McapWriter(tmp_path / "z.mcap")
    w.close()
    w.close()
    with pytest.raises(RuntimeError, match="after close"):
        w.write(_readings()[0])


WORKER = textwrap.dedent("""
    import sys, time
    from tactile_force.edge.outputs.mcap_log import McapWriter
    from tactile_force.edge.reading import ForceReading
    w = McapWriter(sys.argv[1])
    i = 0
    while True:
        w.write(ForceReading("left", 1_000_000 * i, i, 0.5 * i))
        print(i, flush=True)  # reading i is flushed to the file
        i += 1
        time.sleep(0.002)
""")


def test_killed_run_leaves_a_readable_file(tmp_path):
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, "-c", WORKER, str(path)], stdout=subprocess.PIPE, text=True)
    try:
        written = -1
        end = time.monotonic() + 60
        while written < 40 and time.monotonic() < end:
            line = proc.stdout.readline()
            if not line:
                break
            written = int(line)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.stdout.close()
    assert written >= 40, f"worker wrote only {written + 1} readings (exit {proc.returncode})"
    # every flush leaves a complete file (a provisional end): the plain reader, the recovering
    # one and the mcap library's own streaming reader all read every reading flushed before the kill
    for recover in (False, True):
        msgs = list(read_messages(path, recover=recover))
        forces = [WrenchStamped.deserialize(m.data).wrench.force.z for m in msgs if m.topic == "/tactile/force"]
        assert len(forces) >= written + 1  # every reading flushed before the kill, maybe one more
        assert forces == [0.5 * i for i in range(len(forces))]
    from mcap.stream_reader import StreamReader

    with open(path, "rb") as fh:
        seen = sum(type(rec).__name__ == "Message" for rec in StreamReader(fh).records)
    assert seen >= 2 * (written + 1)
