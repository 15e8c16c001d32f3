"""The benchmarks' own commands keep the verbs' promises: a bad argument exits 2 with one line naming it,
before any counting or measuring, and a page is never written over a file given as ``--out``."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.conftest import REPO


def _run(*args: str) -> tuple[int, str, float]:
    t0 = time.monotonic()
    p = subprocess.run([sys.executable, "-m", "benchmarks", *args], capture_output=True, text=True, cwd=REPO,
                       timeout=120)
    return p.returncode, p.stdout + p.stderr, time.monotonic() - t0


def _before(tmp_path: Path, name: str, content: str | None) -> Path:
    p = tmp_path / name
    if content is None:
        p.mkdir()
    else:
        p.write_text(content)
    return p


@pytest.mark.parametrize("name, content, said", [
    ("missing.json", "", "no such file"),
    ("folder", None, "not a file"),
    ("corrupt.json", "{not json", "not readable as JSON"),
    ("keyless.json", "{}", "'commit' (text) and 'variants'"),
    ("shape.json", json.dumps({"commit": "abc", "variants": [{"bundle": "default"}]}), "shape"),
    ("counts.json", json.dumps({"commit": "abc", "variants": [{"bundle": "d", "label": "D", "ratio": 1.0,
                                                               "counts": {"runtime": {"total": "x"}}}]}), "shape"),
])
def test_a_bad_before_record_is_refused_before_any_counting(tmp_path, name, content, said):
    before = tmp_path / name if name == "missing.json" else _before(tmp_path, name, content)
    rc, out, _ = _run("instructions", "--before", str(before), "--out", str(tmp_path / "out"))
    assert rc == 2 and said in out and "--before" in out and "Traceback" not in out, out
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, said", [
    (["instructions", "--variants", "bogus"], "--variants"),
    (["instructions", "--readings", "-1"], "--readings"),
    (["instructions", "--readings", "0"], "--readings"),
    (["cadence", "--rounds", "0"], "--rounds"),
    (["startup", "--runs", "0"], "--runs"),
    (["startup", "--python", "/no/such/python"], "--python"),
    (["cadence", "--before", "x.json"], "--before"),
])
def test_a_bad_argument_exits_2_naming_it_before_any_work(args, said):
    rc, out, seconds = _run(*args)
    assert rc == 2 and said in out and "Traceback" not in out, out
    assert seconds < 60  # nothing was counted or measured


def test_out_onto_a_file_is_refused_and_the_file_is_kept(tmp_path):
    mine = tmp_path / "notes.md"
    mine.write_text("mine")
    rc, out, _ = _run("instructions", "--out", str(mine))
    assert rc == 2 and "--out" in out and "is a file" in out and mine.read_text() == "mine"
