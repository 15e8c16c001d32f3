"""Force labels and meta.jsonl: one reader, the same verdict everywhere.

The dataset reader and quantize --calib refuse a bad label with a LabelError naming the file;
the replay source never dies on one: it logs one warning per bad file and yields truth None.
"""

from __future__ import annotations

import logging

import pytest
from hypothesis import example, given
from tactile_force.edge.data.dataset import AuthorsDataset
from tactile_force.edge.data.labels import MAX_FORCE_N, LabelError, read_force_file
from tactile_force.edge.sources import ReplayFolderSource
from tactile_force.export.calibration import CalibrationData, CalibrationError

from benchmarks.robustness import (
    Outcome,
    expected_label,
    label_bytes,
    make_dataset,
    meta_bytes,
    probe_label,
    probe_meta,
)

from .conftest import ROBUST


@pytest.fixture(scope="module")
def one_sample(tmp_path_factory):
    return make_dataset(tmp_path_factory.mktemp("labels"))


@ROBUST
@given(label_bytes())
@example(b"\xff\xfe\x00bad")  # non-UTF-8: UnicodeDecodeError at 9ed225d
@example(b"-5\n")  # accepted at 9ed225d
@example(b"1e308\n")  # accepted at 9ed225d
@example(b"nan\n")
@example(b"")
@example(b",")  # IndexError at a065227: a first line of separators only
@example(b" ; ,\n2.0\n")
def test_every_reader_agrees_on_every_label(one_sample, data):
    v = probe_label(one_sample, data)
    assert v.ok, v


@pytest.mark.parametrize("data, problem", [
    (b"\xe9t\xe9\n", "not UTF-8"), (b"", "empty"), (b"hello\n", "not a number"), (b"nan\n", "not finite"),
    (b"inf\n", "not finite"), (b"-5\n", "negative"), (b"1e308\n", "physical bound"), (b"201\n", "physical bound"),
])
def test_bad_label_messages_name_the_file_and_the_problem(tmp_path, data, problem):
    p = tmp_path / "force_7.txt"
    p.write_bytes(data)
    with pytest.raises(LabelError, match=problem) as info:
        read_force_file(p)
    assert "force_7.txt" in str(info.value)


def test_missing_label_is_named(tmp_path):
    with pytest.raises(LabelError, match=r"force_1\.txt: force file missing"):
        read_force_file(tmp_path / "force_1.txt")


def test_bound_and_zero(tmp_path):
    p = tmp_path / "force_0.txt"
    for text, want in ((b"0\n", 0.0), (f"{MAX_FORCE_N}\n".encode(), MAX_FORCE_N), (b"\xef\xbb\xbf3.5, 0.1\n", 3.5)):
        p.write_bytes(text)
        assert read_force_file(p) == want == expected_label(text)


def test_real_labels_read(aurova_dir):
    ds = AuthorsDataset(aurova_dir)
    forces = ds.forces()
    assert len(forces) == 11 and 1.0 < forces.min() and forces.max() < 12.0


def test_replay_warns_once_per_bad_label_and_keeps_running(tmp_path, caplog):
    root = make_dataset(tmp_path / "ds", n=4, forces=[1.0, 2.0, 3.0, 4.0])
    (root / "forces" / "force_1.txt").write_bytes(b"\xff\xfe")
    (root / "forces" / "force_2.txt").unlink()
    with caplog.at_level(logging.WARNING, logger="tactile_force.edge.sources.files"):
        for _ in range(2):  # a second pass over the same files warns no more
            src = ReplayFolderSource(root, fps=None)
            truths = [tf.truth_n for tf in src]
            assert truths == [1.0, None, None, 4.0]
    warned = [r.getMessage() for r in caplog.records]
    assert len([w for w in warned if "force_1.txt" in w]) == 2  # once per source (per run)
    assert len([w for w in warned if "force_2.txt" in w]) == 2
    assert any("not UTF-8" in w for w in warned) and any("missing" in w for w in warned)


def test_dataset_reader_and_calib_refuse_a_non_utf8_label(tmp_path):
    root = make_dataset(tmp_path / "ds", n=2)
    (root / "forces" / "force_1.txt").write_bytes(b"1.0\xff\n")
    with pytest.raises(LabelError, match=r"force_1\.txt: not UTF-8"):
        list(AuthorsDataset(root))
    with pytest.raises(CalibrationError, match=r"force_1\.txt: not UTF-8"):
        CalibrationData.from_path(root, "rgbmod", min_frames=1)


@ROBUST
@given(meta_bytes())
def test_meta_jsonl_loads_or_names_file_and_line(tmp_path_factory, data):
    root = make_dataset(tmp_path_factory.mktemp("meta"), n=2)
    v = probe_meta(root, data)
    assert v.ok and v.outcome in (Outcome.ACCEPTED, Outcome.CLEAR), v


@pytest.mark.parametrize("data, line", [(b'{"id": 0}\n{"id": 1, "t": 12', 2), (b"\x89PNG\r\n\x1a\n\x00\x00", 1),
                                        (b'{"id": 0}\n[1]\n', 2)])
def test_truncated_or_binary_meta_names_file_and_line(tmp_path, data, line):
    root = make_dataset(tmp_path / "ds", n=2)
    (root / "meta.jsonl").write_bytes(data)
    with pytest.raises(LabelError, match=rf"meta\.jsonl line {line}"):
        AuthorsDataset(root)
