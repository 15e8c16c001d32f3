"""``python -m benchmarks error``: every shipped bundle's error on the synthetic test split
(rendered alone) and the real frames, through the runtime; the page's table; no timing assertions."""

from __future__ import annotations

import math

import pytest
from tactile_force.edge.scene import default_bundle_path, shipped_bundles
from tactile_force.edge.synthetic import paper_split

import benchmarks.__main__ as cli
from benchmarks import error_vs_runtime as ev
from benchmarks.reference import SPLIT, heldout_test_split


@pytest.fixture(scope="module")
def samples():
    return heldout_test_split(16)


def test_the_test_split_holds_only_the_held_out_indenters_and_renders_the_same_twice(samples):
    test = set(paper_split(SPLIT).test)
    assert len(samples) == 16 and {s[3]["indenter"] for s in samples} <= test
    again = heldout_test_split(16)
    assert all(a[0] == b[0] and (a[1] == b[1]).all() and a[2] == b[2] for a, b in zip(samples, again))


def test_every_shipped_depth_and_rgb_bundle_reads_the_synthetic_split(samples):
    for name, path in shipped_bundles().items():
        e = ev.synthetic_error(path, samples)
        assert e is not None, name
        assert 0 < e.n <= e.with_truth == 16 and e.re_mean is not None and math.isfinite(e.re_mean)
        assert e.re_mean < 1.0 and e.mae_mean >= 0  # a trained bundle, not noise


def test_real_frames_are_skipped_with_a_reason_where_the_shared_data_is_absent(monkeypatch):
    monkeypatch.setattr(ev, "REAL_DATA", ("no_such_folder",))
    assert ev.real_data() is None


def test_real_frames_read_as_run_reads_them():
    real = ev.real_data()
    if real is None:
        pytest.skip("shared data aurova_digit_grasp / aurova_background_b.png absent")
    e = ev.real_error(default_bundle_path(), *real)
    assert e is not None and e.n > 0 and e.re_mean is not None


def test_the_table_has_a_row_per_bundle_and_dashes_what_was_not_measured():
    err = ev.Error(10, 12, 1, 0.1, 0.05, 0.8, 0.4)
    rows = [ev.Row("default", "rgbmod", "int8-static", err, None, 0.4, 0.6, 0.5, 0.7, 0.08),
            ev.Row("d", "d", "int8-static", None, err, 0.5, None, None, None, None)]
    lines = ev.table(rows).splitlines()
    assert len(lines) == 4 and "60 fps total p99 ms" in lines[0]
    assert "| default | rgbmod | int8-static | 0.100 +- 0.050 | 0.800 +- 0.400 | 10 / 12 | - | - | - |" in lines[2]
    assert lines[3].endswith("| - | - | - | - |")


def test_a_quick_run_never_goes_into_the_docs(capsys):
    docs = cli.docs_dir()
    assert docs is not None
    assert cli.main(["error", "--quick", "--out", str(docs)]) == 2
    assert "never go into the docs" in capsys.readouterr().err
