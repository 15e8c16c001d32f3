"""Every numeric argument is range-checked where it enters, tiny and huge values included,
and the error names the flag or parameter the user typed: every numeric flag of every verb
(its parser's type declares a finite range, shared with the options records through
edge/limits.py), the public constructors and options records, scene files."""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from benchmarks.robustness_cli import (
    EXTREME_TEXTS,
    api_numeric_cases,
    cli_numeric_cases,
    cli_numeric_verdict,
    numeric_flags,
    probe_numeric_flag,
)

from .conftest import ROBUST

FLAGS = numeric_flags()


def test_the_numeric_flags_are_found():
    found = {(verb, flag) for verb, flag, _ in FLAGS}
    assert {("run", "--fps"), ("bench", "--fps"), ("bench", "--cadence-frames"), ("demo", "--seed"),
            ("synth", "--n"), ("record", "--every"), ("record", "--fps")} <= found


@pytest.mark.parametrize("text", EXTREME_TEXTS)
def test_every_numeric_flag_refuses_an_extreme_by_name(text):
    bad = [str(v) for verb, flag, action in FLAGS if not (v := probe_numeric_flag(verb, flag, action, text)).ok]
    assert not bad, bad


_TEXTS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.integers(-(10**40), 10**40).map(str),
    st.sampled_from(EXTREME_TEXTS),
)


@ROBUST
@given(index=st.integers(0, len(FLAGS) - 1), text=_TEXTS)
def test_any_number_is_refused_by_name_or_accepted_in_range(index, text):
    verb, flag, action = FLAGS[index]
    v = probe_numeric_flag(verb, flag, action, text)
    assert v.ok, str(v)


@pytest.mark.parametrize("case", api_numeric_cases(), ids=lambda c: c[0])
def test_constructors_refuse_numeric_extremes_naming_the_parameter(case):
    from tactile_force.edge.errors import TactileForceError

    what, call, names = case
    with pytest.raises(TactileForceError) as info:
        call()
    assert all(n in str(info.value) for n in names), str(info.value)


@pytest.mark.parametrize("index", range(len(cli_numeric_cases(Path(".")))))
def test_reported_cli_cases_exit_2_naming_the_flag_and_leave_nothing(tmp_path, index):
    argv, flag = cli_numeric_cases(tmp_path)[index]
    v = cli_numeric_verdict(argv, flag, tmp_path)
    assert v.ok, str(v)


def test_a_scene_file_refuses_a_tiny_frame_rate(tmp_path):
    from tactile_force.edge.errors import SceneError
    from tactile_force.edge.scene import load_scene

    scene = tmp_path / "s.toml"
    scene.write_text('[[sensor]]\nsource = "virtual"\nfps = 1e-300\n')
    with pytest.raises(SceneError, match=r"sensor\[0\]\.fps"):
        load_scene(scene)


def test_a_parameter_error_names_the_flag_that_set_it():
    from tactile_force.edge.cli.main import flag_named

    p = argparse.ArgumentParser()
    p.add_argument("--seed")
    p.add_argument("--max-frames")
    assert flag_named("VirtualDigitSource.seed=-1: expected x", p).startswith("--seed: ")
    assert flag_named("RuntimeOptions.max_frames=0: no", p).startswith("--max-frames: ")
    assert flag_named("--seed -1: expected x", p) == "--seed -1: expected x"
    assert flag_named("seed file missing", p) == "seed file missing"
