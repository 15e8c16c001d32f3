"""`record`: real DIGIT frames + HID scale reports -> authors' layout, surviving interruption."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.errors import DatasetError
from tactile_force.firmware_bridge import G, HidScale, RecordOptions, prepare_output, record

from .fakes import FakeHidDevice
from .record_worker import LoopedFrames, scale_report

WORKER = Path(__file__).with_name("record_worker.py")


def _start(aurova_dir, out):
    return subprocess.Popen([sys.executable, str(WORKER), str(aurova_dir), str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _wait_for_labels(proc, out, n, limit_s=60.0):
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        if len(list((out / "forces").glob("force_*.txt"))) >= n if (out / "forces").is_dir() else False:
            return
        if proc.poll() is not None:
            pytest.fail(f"recorder exited early: {proc.communicate()}")
        time.sleep(0.02)
    proc.kill()
    pytest.fail("recorder wrote nothing in time")


def _check_readable(out):
    data = AuthorsDataset(out)
    samples = list(data)
    for s in samples:
        assert s.frame.shape == (320, 240, 3)
        assert s.force_n == pytest.approx(0.1 * (s.id + 1) * G, rel=1e-5)  # scale sends 100 g * (k + 1)
    return samples


def test_record_pairs_frames_with_scale_force(aurova_dir, tmp_path):
    src = LoopedFrames(str(aurova_dir), 0.0)
    reports = [scale_report(500), [0x03, 0x06, 0x02, 0x00, 0, 0],  # 500 g, then overload
               [0x03, 0x03, 0x02, 0x00, 0xE8, 0x03], scale_report(1500)]  # 1000 g in motion, 1500 g
    scale = HidScale(FakeHidDevice(reports))
    res = record(src, scale, RecordOptions(out=tmp_path / "ds", max_samples=3, stable_only=True))
    assert res.written == [0, 1, 2] and res.stopped_by == "max_samples"
    assert res.skipped == {"scale overload": 1, "scale in motion": 1}
    data = AuthorsDataset(tmp_path / "ds")
    assert data.forces() == pytest.approx([0.5 * G, 1.5 * G, 1.5 * G])
    assert np.array_equal(data[0].frame, src.frames[0])  # lossless PNG round trip of the real frame
    assert data.meta[0]["scale_unit"] == "g" and data.meta[0]["scale_status"] == "stable"


def test_record_stops_cleanly_when_scale_unplugs(aurova_dir, tmp_path):
    scale = HidScale(FakeHidDevice([scale_report(200)] * 3, unplug_after=3))
    res = record(LoopedFrames(str(aurova_dir), 0.0), scale, RecordOptions(out=tmp_path / "ds"))
    assert res.stopped_by.startswith("scale lost") and len(res.written) == 3
    assert len(AuthorsDataset(tmp_path / "ds")) == 3


def test_sigint_mid_recording_leaves_a_readable_dataset(aurova_dir, tmp_path):
    out = tmp_path / "ds"
    proc = _start(aurova_dir, out)
    _wait_for_labels(proc, out, 4)
    proc.send_signal(signal.SIGINT)
    stdout, stderr = proc.communicate(timeout=30)
    assert proc.returncode == 0, stderr
    assert "stopped interrupted" in stdout
    samples = _check_readable(out)
    assert len(samples) >= 4
    assert not list(out.rglob(".*.tmp"))


def test_kill_mid_recording_loses_at_most_the_frame_in_flight(aurova_dir, tmp_path):
    out = tmp_path / "ds"
    proc = _start(aurova_dir, out)
    _wait_for_labels(proc, out, 4)
    proc.kill()  # SIGKILL: no chance to finish the sample in flight
    proc.communicate(timeout=30)
    labelled = len(list((out / "forces").glob("force_*.txt")))
    images = len(list((out / "images").glob("*.png")))
    assert images - labelled in (0, 1)
    next_id, removed = prepare_output(out)  # what the next `record` into this folder does first
    assert len(removed) == images - labelled and next_id == labelled
    assert len(_check_readable(out)) == labelled
    # recording resumes after the last labelled sample
    res = record(LoopedFrames(str(aurova_dir), 0.0), HidScale(FakeHidDevice([scale_report(100 * (labelled + 1))])),
                 RecordOptions(out=out, max_samples=1))
    assert res.written == [labelled]
    assert len(_check_readable(out)) == labelled + 1


def test_unlabelled_frame_is_reported_by_the_reader_until_repaired(aurova_dir, tmp_path):
    out = tmp_path / "ds"
    record(LoopedFrames(str(aurova_dir), 0.0), HidScale(FakeHidDevice([scale_report(100)])),
           RecordOptions(out=out, max_samples=1))
    (out / "images" / "1.png").write_bytes((out / "images" / "0.png").read_bytes())  # a frame in flight
    (out / "forces" / ".force_1.txt.tmp").write_text("0.9")
    with pytest.raises(DatasetError, match="force_1.txt"):
        list(AuthorsDataset(out))
    assert prepare_output(out) == (1, [1])
    assert len(list(AuthorsDataset(out))) == 1 and not os.path.exists(out / "forces" / ".force_1.txt.tmp")


def test_record_command_without_the_sensor_fails_clearly(tmp_path, capsys):
    from tactile_force.edge.cli import main

    assert main(["record", "--sensor", "D99999", "--out", str(tmp_path / "ds")]) == 2  # bad input: exit 2
    assert "DIGIT 'D99999' not attached" in capsys.readouterr().err
    assert not (tmp_path / "ds").exists()
