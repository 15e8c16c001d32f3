"""MCAP logs survive their process: a real ``tactile-force run --out
x.mcap`` (with a CSV beside it as the record of what was written) stopped by SIGTERM,
SIGINT or kill -9, then read back with the ``mcap`` library's own readers:
``make_reader(f).iter_messages()`` (seeking) and ``NonSeekingReader(f).iter_messages()``
(sequential), both with their defaults."""

from __future__ import annotations

import csv
import math
import signal
from pathlib import Path

import pytest

pytest.importorskip("mcap", reason="MCAP output needs the 'mcap' extra")
pytest.importorskip("cyclonedds", reason="MCAP output serialises CDR with cyclonedds (the 'mcap' extra)")

from mcap.reader import make_reader  # noqa: E402

from benchmarks.robustness_mcap import mcap_forces, stopped_run  # noqa: E402
from tests.conftest import shared_data  # noqa: E402


@pytest.fixture(scope="module")
def replay(tmp_path_factory) -> Path:
    """A replay of 198 frames (the 11 real AUROVA presses, 18 times): at --fps 20 a run lasts
    10 s, long enough to be stopped; the CNN gives a force on most of them."""
    from tactile_force.edge.data.dataset import AuthorsDataset, AuthorsDatasetWriter

    real = list(AuthorsDataset(shared_data("aurova_digit_grasp")))
    root = tmp_path_factory.mktemp("mcap_replay") / "replay"
    with AuthorsDatasetWriter(root) as w:
        for i in range(198):
            s = real[i % len(real)]
            w.write(s.frame, s.force_n)
    return root


def _csv_forces(path: Path) -> list[float]:
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    return [float(r["force_n"]) if r["force_n"] not in ("", "nan") else math.nan for r in rows]


def _same(a: list[float], b: list[float]) -> bool:
    return len(a) == len(b) and all((math.isnan(x) and math.isnan(y)) or abs(x - y) < 1e-9 for x, y in zip(a, b))


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_sigterm_and_sigint_finalize_the_log(replay, tmp_path, sig, code):
    done, out_csv, out_mcap = stopped_run(replay, tmp_path, sig)
    assert done.returncode == code, done.stderr[-800:]
    assert f"stopped by {signal.Signals(sig).name}" in done.stderr and "Traceback" not in done.stderr
    written = _csv_forces(out_csv)
    assert 12 <= len(written) < 198
    for sequential in (False, True):
        assert _same(mcap_forces(out_mcap, sequential), written)
    with open(out_mcap, "rb") as fh:  # finalized: a summary with the statistics and chunk indexes
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics is not None and summary.chunk_indexes
    assert summary.statistics.channel_message_counts[next(
        c.id for c in summary.channels.values() if c.topic == "/tactile/force")] == len(written)


def test_kill_9_leaves_every_written_reading_to_the_library_readers(replay, tmp_path):
    done, out_csv, out_mcap = stopped_run(replay, tmp_path, signal.SIGKILL, after=20)
    assert done.returncode == -signal.SIGKILL
    written = _csv_forces(out_csv)  # the CSV sink writes each reading just before the MCAP sink
    for sequential in (False, True):
        got = mcap_forces(out_mcap, sequential)
        assert len(written) - 1 <= len(got) <= len(written), (len(got), len(written))
        assert _same(got, written[:len(got)])
