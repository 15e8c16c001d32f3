"""HID point-of-sale scale reports (layout per the HID POS usage tables) -> newtons."""

import math

import pytest
from tactile_force.edge.errors import SourceError
from tactile_force.firmware_bridge import G, HidScale, ScaleReportError, ScaleStatus, parse_scale_report

from .fakes import FakeHidDevice

OZ_KG, LB_KG = 0.028349523125, 0.45359237


@pytest.mark.parametrize("report, newtons", [
    # report id 3, status 4 (stable), unit 2 (g), exponent 0, 1000 (e8 03) -> 1 kg
    ([0x03, 0x04, 0x02, 0x00, 0xE8, 0x03], 1.0 * G),
    # unit 3 (kg), exponent -3, 2000 -> 2.000 kg
    ([0x03, 0x04, 0x03, 0xFD, 0xD0, 0x07], 2.0 * G),
    # unit 11 (oz), exponent -1, 6452 -> 645.2 oz (DYMO M25 example: 40 lb 5.2 oz)
    ([0x03, 0x04, 0x0B, 0xFF, 0x34, 0x19], 645.2 * OZ_KG * G),
    # unit 12 (lb), exponent -2, 500 -> 5.00 lb
    ([0x03, 0x04, 0x0C, 0xFE, 0xF4, 0x01], 5.0 * LB_KG * G),
    # status 2 (stable at centre of zero)
    ([0x03, 0x02, 0x02, 0x00, 0x00, 0x00], 0.0),
    # status 5 (under zero), magnitude 100 g -> -100 g
    ([0x03, 0x05, 0x02, 0x00, 0x64, 0x00], -0.1 * G),
    # under zero sent as two's complement (-100 = 0xff9c)
    ([0x03, 0x05, 0x02, 0x00, 0x9C, 0xFF], -0.1 * G),
    # 4-byte weight: 1 234 567 mg
    ([0x03, 0x04, 0x01, 0x00, 0x87, 0xD6, 0x12, 0x00], 1.234567 * G),
])
def test_weight_reports_decode_to_newtons(report, newtons):
    r = parse_scale_report(report)
    assert r.force_n == pytest.approx(newtons, rel=1e-9, abs=1e-12)
    assert r.valid


def test_units_and_stability_are_reported():
    r = parse_scale_report([0x03, 0x04, 0x0B, 0xFF, 0x34, 0x19])
    assert (r.unit, r.value, r.stable, r.status) == ("oz", pytest.approx(645.2), True, ScaleStatus.STABLE)
    moving = parse_scale_report([0x03, 0x03, 0x02, 0x00, 0xF4, 0x01])
    assert moving.status is ScaleStatus.IN_MOTION and not moving.stable and moving.valid
    assert moving.force_n == pytest.approx(0.5 * G)


@pytest.mark.parametrize("status", [1, 6, 7, 8])  # fault, overload, needs calibration, needs re-zero
def test_overload_and_faults_carry_no_weight(status):
    r = parse_scale_report([0x03, status, 0x02, 0x00, 0xFF, 0xFF])
    assert not r.valid and not r.stable and math.isnan(r.force_n)


def test_report_without_id_byte():
    # DYMO-style 5 data bytes as some platforms deliver them: status, unit, exponent, lo, hi
    r = parse_scale_report([0x04, 0x02, 0x00, 0x14, 0x00], has_report_id=False)
    assert r.force_n == pytest.approx(0.020 * G)


def test_tare_offset_is_subtracted():
    r = parse_scale_report([0x03, 0x04, 0x02, 0x00, 0xE8, 0x03], tare_n=0.5 * G)
    assert r.force_n == pytest.approx(0.5 * G)


@pytest.mark.parametrize("report, words", [
    ([0x03, 0x04, 0x02], "expected >= 5"),
    ([0x04, 0x04, 0x02, 0x00, 0x00, 0x00], "report id 4"),
    ([0x03, 0x09, 0x02, 0x00, 0x00, 0x00], "status 9"),
    ([0x03, 0x04, 0x0D, 0x00, 0x01, 0x00], "weight unit 13"),
    ([], "report id None"),
])
def test_bad_reports_are_named(report, words):
    with pytest.raises(ScaleReportError, match=words):
        parse_scale_report(report)


def test_scale_returns_newest_report_and_tares():
    dev = FakeHidDevice([[0x03, 0x04, 0x02, 0x00, 0xC8, 0x00],  # 200 g
                         [0x03, 0x04, 0x02, 0x00, 0x2C, 0x01]])  # 300 g
    scale = HidScale(dev)
    assert scale.read().force_n == pytest.approx(0.2 * G)
    assert scale.tare() == pytest.approx(0.3 * G)
    assert scale.read().force_n == pytest.approx(0.0, abs=1e-12)  # scale re-sends 300 g


def test_scale_skips_non_weight_reports_and_reports_unplug():
    dev = FakeHidDevice([[0x04, 0x04], [0x03, 0x04, 0x02, 0x00, 0x64, 0x00]], unplug_after=2)
    scale = HidScale(dev)
    assert scale.read() is None  # a status report is not a weight
    assert scale.read().force_n == pytest.approx(0.1 * G)
    with pytest.raises(SourceError, match="unplugged"):
        scale.read()
