"""A background given to the runtime is checked for a press: an 11.9 N
frame of the AUROVA grasp given as ``--background`` is warned about loudly and the readings
it would turn into "no contact, 0 N" are flagged ``background_mismatch`` with no force.

Real AUROVA frames and backgrounds, real ONNX Runtime, the CLI as a user runs it.
"""

from __future__ import annotations

import csv
import math

import cv2
import pytest
from tactile_force.edge import ContactGate, Flags, ForceRuntime, OnnxForceModel, RuntimeOptions, Sensor
from tactile_force.edge.cli import main as cli_main
from tactile_force.edge.scene import default_bundle_path
from tactile_force.edge.sources import ReplayFolderSource

from tests.conftest import shared_data

HOME = "aurova_background_b.png"
PRESS = "1520.png"  # 11.88 N


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """The default bundle calibrated on the AUROVA grasp (the unit's no-contact image recorded)."""
    out = tmp_path_factory.mktemp("pressed") / "calibrated"
    args = ["calibrate-force", str(default_bundle_path()), "--data", str(shared_data("aurova_digit_grasp")),
            "--out", str(out)]
    rc = cli_main([*args, "--background", str(shared_data("digit_backgrounds", HOME))])
    assert rc == 0 or cli_main(args) == 0  # c1733e6 had no --background
    return out


def _run(model, background, aurova_dir):
    gate = ContactGate()
    gate.capture_background([background], origin="test background")
    rt = ForceRuntime([Sensor("left", ReplayFolderSource(aurova_dir), gate)], model,
                      RuntimeOptions(deadline_ms=1e9))
    out: list = []
    rt.run(on_reading=out.append)
    return out


def _silent_zero(readings) -> list:
    """Readings that say 'no contact, 0 N' unflagged while the sensor is pressed (> 1 N)."""
    return [r for r in readings if r.truth_n and r.truth_n > 1.0 and Flags.NO_CONTACT in r.flags
            and not (r.flags & (Flags.BACKGROUND_MISMATCH | Flags.INVALID_INPUT)) and r.force_n == 0.0]


def test_a_pressed_background_flags_the_no_contact_readings_it_causes(calibrated, aurova_dir):
    pressed = cv2.imread(str(aurova_dir / "images" / PRESS))
    readings = _run(OnnxForceModel(calibrated), pressed, aurova_dir)
    assert len(readings) == 11
    assert not _silent_zero(readings), [(r.truth_n, r.force_n) for r in _silent_zero(readings)]
    flagged = [r for r in readings if Flags.BACKGROUND_MISMATCH in r.flags]
    assert flagged and all(math.isnan(r.force_n) for r in flagged)
    assert any("like a press" in r.detail for r in flagged)  # the others: the gate's own "does not fit"
    assert not any("fitted on another sensor" in r.detail for r in readings)  # the same unit, pressed background


def test_a_no_contact_background_of_the_same_unit_is_not_flagged(calibrated, aurova_dir):
    readings = _run(OnnxForceModel(calibrated), cv2.imread(str(shared_data("digit_backgrounds", HOME))), aurova_dir)
    assert not any(Flags.BACKGROUND_MISMATCH in r.flags for r in readings)


def test_data_stats_with_a_background_are_a_reference_too(aurova_dir):
    """An uncalibrated bundle whose data statistics were recorded with a no-contact background."""
    from tactile_force.edge.fitting.data_stats import compute_data_stats

    model = OnnxForceModel(default_bundle_path())
    frames = [cv2.imread(str(p)) for p in sorted((aurova_dir / "images").glob("*.png"))]
    model.bundle.manifest.data_stats = compute_data_stats(frames, cv2.imread(str(shared_data("digit_backgrounds",
                                                                                               HOME))))
    readings = _run(model, cv2.imread(str(aurova_dir / "images" / PRESS)), aurova_dir)
    assert not _silent_zero(readings)


def test_run_warns_loudly_about_a_pressed_background(calibrated, aurova_dir, tmp_path, capsys):
    out = tmp_path / "readings.csv"
    rc = cli_main(["run", "--source", str(aurova_dir), "--bundle", str(calibrated), "--background",
                   str(aurova_dir / "images" / PRESS), "--out", str(out)])
    err = capsys.readouterr().err
    assert rc == 0 and "like a press" in err and "Traceback" not in err
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows and any("background_mismatch" in r.get("flags", "") for r in rows)
