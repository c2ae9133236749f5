"""Within-family pairs: construction on a hand-made fleet, slope and mean absolute difference by hand."""
import numpy as np
import pytest

from bev_mdo.models import pairs as pr


def test_pairs_need_one_family_and_a_different_drive_power_or_mass():
    family = ["kia ev6", "kia ev6", "kia ev6", "kia ev6", "tesla model 3", "tesla model y", "kia ev6"]
    drive = ["R", "A", "R", "4", "R", "R", "R"]
    power = [125.0, 239.0, 125.0, 239.0, 192.0, 209.0, 168.0]
    mass = [1928.0, 2155.0, 1928.0, 2155.0, 1928.0, 1928.0, 2041.0]
    usable = [True, True, True, True, True, True, False]
    got = pr.find_pairs(family, drive, power, mass, usable)
    # 0 and 2 differ only in wheels (same spec); 1 and 3 too ("A" and "4" are both all-wheel);
    # the two Teslas are different families; row 6 is an outlier
    assert got == [(0, 1), (0, 3), (1, 2), (2, 3)]
    assert pr.find_pairs(family, drive, power, mass)[-1] == (3, 6)
    assert pr.find_pairs(["a", "b"], ["R", "R"], [1.0, 2.0], [1.0, 2.0]) == []


def test_percentage_difference_slope_and_mean_abs_diff_by_hand():
    pairs = [(0, 1), (0, 2), (1, 2)]
    measured = np.array([100.0, 110.0, 120.0])
    predicted = np.array([200.0, 216.0, 224.0])
    x = pr.pct_diff(measured, pairs)
    y = pr.pct_diff(predicted, pairs)
    assert x == pytest.approx([10.0, 20.0, 100 * (120 / 110 - 1)])
    assert y == pytest.approx([8.0, 12.0, 100 * (224 / 216 - 1)])
    s = pr.pair_stats([10.0, 20.0], [8.0, 12.0])
    # slope through the origin: (10*8 + 20*12) / (10^2 + 20^2) = 320 / 500
    assert s["n"] == 2 and s["slope_through_origin"] == pytest.approx(0.64)
    assert s["mean_abs_diff_points"] == pytest.approx(5.0)  # (2 + 8) / 2
    assert s["slope_met"] is False and s["mean_abs_diff_met"] is False and s["targets_met"] is False
    s = pr.pair_stats([10.0, -4.0], [11.0, -4.0])
    assert s["slope_through_origin"] == pytest.approx(126 / 116)  # (110 + 16) / (100 + 16) = 1.086
    assert s["mean_abs_diff_points"] == pytest.approx(0.5)
    assert s["targets_met"] is True


def test_no_pairs_gives_no_figures():
    s = pr.pair_stats([], [])
    assert s["n"] == 0 and s["slope_through_origin"] is None and s["mean_abs_diff_points"] is None
    assert s["targets_met"] is None


def test_drive_classes():
    assert [pr.drive_class(d) for d in ("F", "r", "A", "4", "P", "")] == ["F", "R", "AWD", "AWD", "AWD", ""]
