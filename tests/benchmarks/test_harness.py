"""Quick tests of the benchmark harness (benchmarks/harness/: percentiles, tables, per-stage
arithmetic, the in-memory sources, where the repository, cache and shared data are) and of
``python -m benchmarks``'s guards; no wall-clock assertions."""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np
import pytest

import benchmarks.__main__ as cli
from benchmarks.harness import paths
from benchmarks.harness.latency import LatencyCase, ModelConfig, measure, parse_config
from benchmarks.harness.stats import fmt, markdown_table, percentiles


def test_percentiles_of_known_sample_and_nan_handling():
    p = percentiles(np.arange(1, 101, dtype=float).tolist() + [math.nan])
    assert p.n == 100
    assert p.p50 == pytest.approx(50.5)
    assert p.p90 == pytest.approx(90.1)
    assert p.p99 == pytest.approx(99.01)
    assert math.isnan(percentiles([]).p50) and percentiles([math.inf]).n == 0


def test_markdown_table_formats_and_rejects_ragged_rows():
    t = markdown_table(["a", "b", "c"], [[1, 0.12345, None], ["x", math.nan, 2.5]], digits=2)
    lines = t.splitlines()
    assert lines[0] == "| a | b | c |" and lines[1] == "|---|---|---|"
    assert lines[2] == "| 1 | 0.12 | - |" and lines[3] == "| x | - | 2.50 |"
    with pytest.raises(ValueError, match="row 0 has 2 cells"):
        markdown_table(["a", "b", "c"], [[1, 2]])
    assert fmt(3) == "3" and fmt("s") == "s"


def test_config_names_round_trip():
    for c in (ModelConfig("rgbmod", 0.25, 4), ModelConfig("rgbmod+d", 1.0, 1), ModelConfig("dmod", 0.125, 8)):
        assert parse_config(c.name) == c
    with pytest.raises(ValueError, match="VARIANT-wWIDTH-sK"):
        parse_config("resnet")


def test_quick_never_writes_the_docs_and_default_out_is_not_docs(capsys):
    docs = cli.docs_dir()
    assert docs is not None  # tests run from the clone
    before = {p: p.stat().st_mtime_ns for p in docs.glob("*")} if docs.is_dir() else {}
    assert cli.main(["stability", "--quick", "--out", str(docs)]) == 2
    assert "never go into the docs" in capsys.readouterr().err
    assert cli.main(["trust", "--quick", "--out", str(docs / "sub")]) == 2
    after = {p: p.stat().st_mtime_ns for p in docs.glob("*")} if docs.is_dir() else {}
    assert before == after
    assert not cli.is_docs(cli.default_out()) and cli.is_docs(docs)
    assert cli.main([]) == 2  # no page named: the help


def test_measure_through_the_runtime_with_a_fake_clock():
    """Every clock call advances 0.25 ms. Per frame the runtime reads the clock before and after
    read() (the in-memory source stamps arrival in between), after the gate, after the depth
    stage, around predict and at the end: source 0.5, gate / depth / inference 0.25 each,
    total (from arrival) 1.5, glue 0.75 ms. The shipped D bundle with its own depth stage."""
    from tactile_force.edge.bundle.store import load_bundle
    from tactile_force.edge.runtime import build_depth_stage
    from tactile_force.edge.scene import shipped_bundles

    from benchmarks.harness.frames import frame_pool

    pool = frame_pool()  # 64 virtual DIGIT frames in contact, rendered once and cached
    d = shipped_bundles()["d"]
    manifest = load_bundle(d).manifest
    ticks = itertools.count(step=250_000)
    res = measure(LatencyCase(ModelConfig("d", 0.125, 4), "int8-static", frames=12, warmup=2, bundle=d), pool,
                  clock=lambda: next(ticks), bare=False, depth=lambda: build_depth_stage(None, manifest))
    s = res.stages
    assert s["source"].n == 12 and res.bare is None and math.isnan(res.overhead)
    assert s["source"].p50 == pytest.approx(0.5)
    for k in ("gate", "depth", "inference"):
        assert s[k].p50 == pytest.approx(0.25) and s[k].p99 == pytest.approx(0.25)
    assert s["total"].p99 == pytest.approx(1.5) and s["glue"].p50 == pytest.approx(0.75)
    assert s["gate+inference"].p50 == pytest.approx(0.5)
    assert "gate open" not in res.note  # every rendered frame is in contact


def test_measure_at_a_cadence_refuses_a_bad_fps_or_an_injected_clock():
    """A paced source stamps frames with time.monotonic_ns: a fake runtime clock would mix two
    time bases, so it is refused, as is an fps that is no finite positive number."""
    from tactile_force.edge.scene import default_bundle_path

    case = LatencyCase(ModelConfig("rgbmod", 0.25, 4), "int8-static", frames=2, warmup=0, bundle=default_bundle_path())
    with pytest.raises(ValueError, match="injected clock"):
        measure(case, None, clock=lambda: 0, bare=False, fps=60.0)
    for fps in (0.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="fps"):
            measure(case, None, bare=False, fps=fps)


def test_memory_source_stamps_arrival_and_ends():
    from benchmarks.harness.sources import MemorySource

    frames = np.arange(3, dtype=np.uint8)[:, None, None, None] * np.ones((1, 320, 240, 3), np.uint8)
    ticks = itertools.count(start=10, step=5)
    src = MemorySource(frames, 4, clock=lambda: next(ticks))
    got = list(src)
    assert [f.index for f in got] == [0, 1, 2, 3] and [f.arrival_ns for f in got] == [10, 15, 20, 25]
    assert [int(f.frame[0, 0, 0]) for f in got] == [0, 1, 2, 0]  # cycled, no copies needed
    assert np.shares_memory(got[3].frame, frames) and src.read() is None


def test_paced_memory_source_stamps_arrival_and_skips_what_a_late_reader_missed():
    import time

    from benchmarks.harness.sources import PacedMemorySource

    frames = np.zeros((2, 320, 240, 3), np.uint8)
    src = PacedMemorySource(frames, fps=1000.0, n=200)
    a = src.read()
    assert a.index == 0 and a.arrival_ns >= a.timestamp_ns and a.meta["superseded"] == []
    time.sleep(0.02)  # 20 frame periods: the reader is late
    b = src.read()
    assert b.index >= 10 and b.arrival_ns == b.timestamp_ns  # it waited in the buffer since it fell due
    assert [k for k, _ in b.meta["superseded"]] == list(range(1, b.index)) and src.stats.dropped == b.index - 1


def test_the_clone_is_found_and_an_installed_copy_has_none(tmp_path, monkeypatch):
    root = paths.repo_root()
    assert root is not None and (root / "benchmarks" / "harness" / "paths.py").is_file()
    assert paths.require_repo("this test") == root
    # the same file laid out as installed (site-packages/tactile_force/benchmarks/harness/paths.py)
    installed = tmp_path / "site-packages" / "tactile_force" / "benchmarks" / "harness" / "paths.py"
    installed.parent.mkdir(parents=True)
    installed.write_text(Path(paths.__file__).read_text())
    monkeypatch.setattr(paths, "__file__", str(installed))
    assert paths.repo_root() is None
    with pytest.raises(paths.SetupError, match="writing the docs needs a clone"):
        paths.require_repo("writing the docs")
    monkeypatch.delenv(paths.SHARED_DATA_ENV, raising=False)
    with pytest.raises(paths.SetupError, match=paths.SHARED_DATA_ENV):
        paths.shared_data()
    monkeypatch.setenv(paths.SHARED_DATA_ENV, str(tmp_path / "data"))
    assert paths.shared_data("x.png") == tmp_path / "data" / "x.png"
    monkeypatch.delenv(paths.CACHE_ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert paths.cache_dir() == tmp_path / "xdg" / "tactile_force" / "benchmarks"
    assert paths.source_commit().startswith("none (installed")


def test_cache_and_shared_data_follow_their_variables(tmp_path, monkeypatch):
    monkeypatch.setenv(paths.CACHE_ENV, str(tmp_path / "c"))
    monkeypatch.setenv(paths.SHARED_DATA_ENV, str(tmp_path / "d"))
    assert paths.cache_dir() == tmp_path / "c" and paths.shared_data("a", "b") == tmp_path / "d" / "a" / "b"
    monkeypatch.delenv(paths.CACHE_ENV)
    monkeypatch.delenv(paths.SHARED_DATA_ENV)
    root = paths.repo_root()
    assert root is not None
    assert paths.cache_dir() == root / "benchmarks" / "cache" and paths.shared_data() == root.parent / "shared" / "data"


def test_a_page_header_names_the_commit_that_measured():
    from benchmarks.harness.machine import describe_machine, header

    text = header("T", "python -m benchmarks x", describe_machine())
    line = next(ln for ln in text.splitlines() if ln.startswith("Commit: "))
    assert line.split()[1] == paths.source_commit().split()[0] and len(line.split()[1]) >= 7


def test_a_setup_error_is_one_line_and_exit_2(monkeypatch, capsys, tmp_path):
    monkeypatch.setattr(paths, "__file__", str(tmp_path / "tactile_force" / "benchmarks" / "harness" / "paths.py"))
    monkeypatch.delenv(paths.SHARED_DATA_ENV, raising=False)
    assert cli.main(["trust", "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and paths.SHARED_DATA_ENV in err

