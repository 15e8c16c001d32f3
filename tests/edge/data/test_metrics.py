"""The paper's RE and MAE (edge/data/metrics.py) against values computed by hand."""

from __future__ import annotations

import math

import pytest
from tactile_force.edge.data.metrics import error_report, error_stats, force_bin_label, relative_error


def test_relative_error_by_hand():
    # |2-1|/1 = 1, |4-5|/5 = 0.2, |9-10|/10 = 0.1
    assert relative_error([2.0, 4.0, 9.0], [1.0, 5.0, 10.0]).tolist() == pytest.approx([1.0, 0.2, 0.1])


def test_error_stats_by_hand():
    s = error_stats([2.0, 4.0, 9.0], [1.0, 5.0, 10.0])
    # RE mean = 1.3 / 3; population std over (1, 0.2, 0.1)
    m = 1.3 / 3
    assert s.re_mean == pytest.approx(0.433333, abs=1e-6)
    assert s.re_std == pytest.approx(math.sqrt(((1 - m) ** 2 + (0.2 - m) ** 2 + (0.1 - m) ** 2) / 3))
    assert s.re_std == pytest.approx(0.402768, abs=1e-6)
    assert (s.mae_mean, s.mae_std, s.n, s.n_excluded_re) == (1.0, 0.0, 3, 0)


def test_mae_spread_and_zero_truth_excluded_from_re():
    # errors 0.5, 1.5, 3.0 N -> MAE mean 5/3, std sqrt(((0.5-5/3)^2+(1.5-5/3)^2+(3-5/3)^2)/3)
    s = error_stats([2.5, 6.5, 3.0], [2.0, 5.0, 0.0])
    assert s.mae_mean == pytest.approx(5 / 3)
    assert s.mae_std == pytest.approx(1.0274023, abs=1e-6)
    assert s.n_excluded_re == 1
    assert s.re_mean == pytest.approx((0.25 + 0.3) / 2) and s.re_std == pytest.approx(0.025)


def test_per_bin_and_per_group_by_hand():
    truth = [1.0, 1.9, 2.0, 14.99]
    pred = [1.5, 1.9, 1.0, 15.99]
    r = error_report(pred, truth, groups={"shape": ["star", "star", "circle", "circle"]})
    assert list(r.per_bin) == ["1-2", "2-3", "14-15"]  # left-closed 1 N bins
    assert r.per_bin["1-2"].n == 2 and r.per_bin["1-2"].re_mean == pytest.approx(0.25)
    assert r.per_bin["2-3"].re_mean == pytest.approx(0.5) and r.per_bin["2-3"].mae_mean == pytest.approx(1.0)
    assert r.per_group["shape"]["star"].mae_mean == pytest.approx(0.25)
    assert r.per_group["shape"]["circle"].re_mean == pytest.approx((0.5 + 1 / 14.99) / 2)
    assert force_bin_label(3.999) == "3-4" and force_bin_label(4.0) == "4-5"
    d = r.as_dict()
    assert d["overall"]["n"] == 4 and d["per_group"]["shape"]["star"]["n"] == 2


def test_metric_input_errors():
    with pytest.raises(ValueError, match="NaN"):
        error_stats([1.0, float("nan")], [1.0, 2.0])
    with pytest.raises(ValueError, match="samples"):
        error_stats([1.0], [1.0, 2.0])
    with pytest.raises(ValueError, match="no samples"):
        error_stats([], [])
    with pytest.raises(ValueError, match="group 'shape'"):
        error_report([1.0, 2.0], [1.0, 2.0], groups={"shape": ["a"]})
