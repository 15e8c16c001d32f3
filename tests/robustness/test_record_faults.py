"""Faults during `record`: kill -9 at each write phase, a power cut that truncates meta.jsonl,
a full disk (a real small tmpfs when root, else a simulated ENOSPC), repair without hardware."""

from __future__ import annotations

import json

import pytest
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.data.labels import LabelError
from tactile_force.firmware_bridge.recorder import RecordOptions, record, repair_dataset

from benchmarks.robustness import (
    KILL_PHASES,
    FixedScale,
    NoiseFrames,
    Outcome,
    make_dataset,
    probe_disk_full,
    probe_kill,
    probe_truncation,
    run_cli,
)


@pytest.mark.parametrize("phase", KILL_PHASES)
def test_kill_9_at_each_write_phase_loses_no_complete_sample(tmp_path, phase):
    v = probe_kill(tmp_path, phase)
    assert v.ok, v


@pytest.mark.parametrize("cut", [1, 7, 15])
def test_truncated_meta_line_is_named_then_repaired(tmp_path, cut):
    v = probe_truncation(tmp_path, cut)
    assert v.ok and v.outcome is Outcome.CLEAR, v


def test_resume_repairs_a_truncated_last_line_instead_of_appending_to_it(tmp_path):
    """9ed225d appended the next record onto the broken line: the dataset stayed unloadable."""
    out = make_dataset(tmp_path / "ds", n=3)
    meta = out / "meta.jsonl"
    meta.write_bytes(meta.read_bytes()[:-9])  # power cut inside the last record (sample 2 stays labelled)
    with pytest.raises(LabelError, match="line 3"):
        AuthorsDataset(out)
    res = record(NoiseFrames(), FixedScale(2.0), RecordOptions(out=out, max_samples=2, handle_signals=False))
    assert res.written == [3, 4] and res.repairs[0].meta_lines_dropped == 1
    ds = AuthorsDataset(out)
    assert [s.id for s in ds] == [0, 1, 2, 3, 4]
    assert sorted(ds.meta) == [0, 1, 3, 4]  # sample 2's record was cut by the power cut; its sample is kept
    assert all(json.loads(line) for line in meta.read_text().splitlines())


def test_disk_full_stops_cleanly_with_the_summary(tmp_path):
    v, method = probe_disk_full(tmp_path)
    print(f"disk full via {method}")
    assert v.ok and v.outcome is Outcome.CLEAR, f"{method}: {v}"


def test_repair_without_hardware(tmp_path):
    out = make_dataset(tmp_path / "ds", n=2)
    (out / "images" / "2.png").write_bytes((out / "images" / "1.png").read_bytes())  # frame whose label never landed
    with open(out / "meta.jsonl", "a") as fh:
        fh.write('{"id": 2, "k"')
    rc, stdout, stderr = run_cli(["record", "--repair", str(out)])
    assert rc == 0, stderr
    assert "removed 1 frame(s) without a label [2]" in stdout and "2 labelled sample(s) read back" in stdout
    assert repair_dataset(out).changed is False
    rc, stdout, _ = run_cli(["record", "--repair", str(out)])
    assert rc == 0 and "nothing to repair" in stdout


def test_repair_reports_a_bad_label_it_cannot_fix(tmp_path):
    out = make_dataset(tmp_path / "ds", n=2)
    (out / "forces" / "force_1.txt").write_bytes(b"-3\n")
    rc, _, stderr = run_cli(["record", "--repair", str(out)])
    assert rc == 1 and "force_1.txt" in stderr and "negative" in stderr


class ThreeFrames(NoiseFrames):
    def read(self):
        return super().read() if self.i < 3 else None


def test_scale_readings_outside_the_label_range_are_skipped_not_written(tmp_path):
    res = record(ThreeFrames(), FixedScale(250.0), RecordOptions(out=tmp_path / "ds", handle_signals=False))
    assert res.written == [] and res.skipped == {"force outside the label range": 3}
    assert res.stopped_by == "source ended"


def test_a_second_recorder_or_a_repair_is_refused_while_one_records(tmp_path):
    """A second writer would 'repair' away the first one's sample in flight."""
    from tactile_force.edge.files.claim import OutputBusy, OutputClaim

    out = make_dataset(tmp_path / "ds", n=2)
    with OutputClaim(out, "record", inside=True):  # a recorder at work there
        with pytest.raises(OutputBusy, match="is writing it now"):
            record(NoiseFrames(), FixedScale(2.0), RecordOptions(out=out, max_samples=1, handle_signals=False))
        rc, _, stderr = run_cli(["record", "--repair", str(out)])
        assert rc == 2 and f"--repair {out}" in stderr and "is writing it now" in stderr
    res = record(NoiseFrames(), FixedScale(2.0), RecordOptions(out=out, max_samples=1, handle_signals=False))
    assert res.written == [2] and not (out / ".tactile-force-claim").exists()
