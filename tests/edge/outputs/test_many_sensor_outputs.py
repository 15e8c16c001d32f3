"""The file outputs of a runtime serving four sensors: the CSV has every sensor's rows, the
MCAP log every sensor's readings (frame_id = the sensor's name, its own time stamps) and its
own image and contact-mask topics. Real runtime, real ONNX Runtime session (the shipped
default bundle), real DIGIT frames, real files read back."""

from __future__ import annotations

import csv
from collections import Counter

import pytest
from tactile_force.edge.gate.contact_gate import ContactGate
from tactile_force.edge.model.onnx_model import OnnxForceModel
from tactile_force.edge.outputs import CsvWriter
from tactile_force.edge.runtime import ForceRuntime, RuntimeOptions, Sensor
from tactile_force.edge.scene import default_bundle_path
from tactile_force.edge.sources import ReplayFolderSource, load_background

from tests.conftest import shared_data

NAMES = ("thumb", "index", "middle", "ring")


def four_finger_runtime(aurova_dir) -> ForceRuntime:
    """Four sensors replaying the 11 real AUROVA frames, each with its own source and gate."""
    bg = load_background(shared_data("digit_backgrounds", "aurova_background_b.png"))
    sensors = []
    for name in NAMES:
        gate = ContactGate()
        gate.capture_background(bg)
        sensors.append(Sensor(name, ReplayFolderSource(aurova_dir, name=name), gate))
    return ForceRuntime(sensors, OnnxForceModel(default_bundle_path()), RuntimeOptions(deadline_ms=1e6))


def test_csv_has_every_sensors_rows(tmp_path, aurova_dir):
    path = tmp_path / "hand.csv"
    rt = four_finger_runtime(aurova_dir)
    readings = []
    with CsvWriter(path) as w:
        rt.run([w], on_reading=readings.append)
    rt.close()
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(readings) == 4 * 11
    for name in NAMES:
        mine = [r for r in rows if r["sensor"] == name]
        want = [r for r in readings if r.sensor == name]
        assert [int(r["frame_index"]) for r in mine] == list(range(11))
        assert [int(r["timestamp_ns"]) for r in mine] == [r.timestamp_ns for r in want]
        assert [float(r["force_n"]) for r in mine] == [r.force_n for r in want]


def test_mcap_has_every_sensors_readings_frames_and_masks(tmp_path, aurova_dir):
    pytest.importorskip("mcap", reason="MCAP output needs the 'mcap' extra")
    pytest.importorskip("cyclonedds", reason="MCAP output serialises CDR with cyclonedds (the 'mcap' extra)")
    from tactile_force.edge.outputs.mcap_log import McapWriter, read_messages
    from tactile_force.edge.outputs.ros2_messages import CompressedImage, WrenchStamped
    from tactile_force.edge.outputs.ros2_names import StampClock

    path = tmp_path / "hand.mcap"
    rt = four_finger_runtime(aurova_dir)
    readings = []
    with McapWriter(path, frames=True, mask=True, stamp_clock=StampClock(offset_ns=0)) as w:
        rt.run([w], on_reading=readings.append)
    rt.close()
    msgs = list(read_messages(path))
    counts = Counter(m.topic for m in msgs)
    assert counts["/tactile/force"] == counts["/tactile/force/diagnostics"] == 4 * 11
    for name in NAMES:
        assert counts[f"/tactile/{name}/image/compressed"] == counts[f"/tactile/{name}/contact_mask/compressed"] == 11
        images = [CompressedImage.deserialize(m.data) for m in msgs if m.topic == f"/tactile/{name}/image/compressed"]
        assert {i.header.frame_id for i in images} == {name}
    wrenches = [WrenchStamped.deserialize(m.data) for m in msgs if m.topic == "/tactile/force"]
    for name in NAMES:
        mine = [wr for wr in wrenches if wr.header.frame_id == name]
        want = [r for r in readings if r.sensor == name]
        assert [divmod(r.timestamp_ns, 10**9) for r in want] == [(wr.header.stamp.sec, wr.header.stamp.nanosec)
                                                                 for wr in mine]
        assert [wr.wrench.force.z for wr in mine] == pytest.approx([r.force_n for r in want])
