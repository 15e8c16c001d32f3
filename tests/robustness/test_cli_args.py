"""Bad arguments exit 2 with a message naming the flag, never a traceback; quantize's
calibration frames must have the channels the model takes."""

from __future__ import annotations

import pytest

from benchmarks.robustness import calib_channel_cases, cli_cases, cli_verdict, probe_calib_channels


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("args")


N_CLI_CASES = 12


def test_every_cli_case_is_run(folder):
    assert len(cli_cases(folder)) == N_CLI_CASES


@pytest.mark.parametrize("index", range(N_CLI_CASES))
def test_bad_arguments_exit_2_naming_the_flag(folder, index):
    argv, codes, names = cli_cases(folder)[index]
    v = cli_verdict(argv, codes, True, names)
    assert v.ok, v


@pytest.mark.parametrize("index", range(3))
def test_calibration_frames_with_the_wrong_channels_are_refused(folder, index):
    what, variant, path = calib_channel_cases(folder)[index]
    v = probe_calib_channels(variant, path)
    assert v.ok, f"{what}: {v}"


def test_max_frames_zero_is_not_unlimited(tmp_path):
    from tactile_force.export.calibration import CalibrationData, CalibrationError

    from benchmarks.robustness import make_dataset

    root = make_dataset(tmp_path / "ds", n=3)
    with pytest.raises(CalibrationError, match="limit=0"):
        CalibrationData.from_path(root, "rgbmod", limit=0)
    assert len(CalibrationData.from_path(root, "rgbmod", limit=2)) == 2
