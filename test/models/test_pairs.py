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


def test_the_pair_figures_do_not_depend_on_the_row_order():
    """100 (E_B / E_A - 1), A the earlier row, moved the held-out slope and mean difference by up to 0.3
    points when the same fleet's rows were reversed (UDDS 0.857 / 3.68 against 0.878 / 3.40)."""
    rng = np.random.default_rng(3)
    measured, predicted = rng.uniform(100, 220, 12), rng.uniform(100, 220, 12)
    pairs = [(a, b) for a in range(12) for b in range(a + 1, 12) if (a + b) % 3 == 0]
    swapped = [(b, a) for a, b in pairs]
    assert pr.pct_diff(measured, swapped) == pytest.approx(-pr.pct_diff(measured, pairs))
    one = pr.pair_stats(pr.pct_diff(measured, pairs), pr.pct_diff(predicted, pairs))
    other = pr.pair_stats(pr.pct_diff(measured, swapped), pr.pct_diff(predicted, swapped))
    assert one["slope_through_origin"] == pytest.approx(other["slope_through_origin"], rel=1e-12)
    assert one["mean_abs_diff_points"] == pytest.approx(other["mean_abs_diff_points"], rel=1e-12)


def test_percentage_difference_slope_and_mean_abs_diff_by_hand():
    pairs = [(0, 1), (0, 2), (1, 2)]
    measured = np.array([100.0, 110.0, 120.0])
    predicted = np.array([200.0, 216.0, 224.0])
    x = pr.pct_diff(measured, pairs)
    y = pr.pct_diff(predicted, pairs)
    assert x == pytest.approx([200 * 10 / 210, 200 * 20 / 220, 200 * 10 / 230])  # percent of the pair's mean
    assert y == pytest.approx([200 * 16 / 416, 200 * 24 / 424, 200 * 8 / 440])
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


def test_model_lines_refine_families_by_pack_voltage():
    """Audi's e-tron SUV (400 V) and e-tron GT (800 V) share the name 'e-tron' but not a platform:
    two model lines in one cross-validation family; names without a voltage conflict stay as they are."""
    from bev_mdo.models import fleet as fl

    f = fl.read_fleet()
    family, line = f.family(), f.model_line()
    gt = [i for i, m in enumerate(f.model) if m.endswith("e-tron GT")]
    suv = [i for i, m in enumerate(f.model) if "quattro" in m or m == "e-tron S"]
    assert gt and suv and {family[i] for i in gt + suv} == {"audi e-tron"}
    assert {line[i] for i in gt} == {"audi e-tron 800 V"} and {line[i] for i in suv} == {"audi e-tron 400 V"}
    assert all(line[i] == family[i] for i in range(len(f)) if f.make[i] != "AUDI")
    # a model line never spans two families, so a pair's two vehicles are held out together
    assert all(len({family[i] for i in range(len(f)) if line[i] == name}) == 1 for name in set(line))


@pytest.fixture(scope="module")
def family_cv_pairs():
    from bev_mdo.models import calibrate as cal
    from bev_mdo.models import fleet as fl

    f = fl.read_fleet()
    cycles = fl.resampled_cycles()
    use = cal.usable(f, cycles)
    cv = cal.cross_validate(f, 5, cycles=cycles, use=use, model="chain")
    return cv, cal.cv_pairs(f, cv, use)


def test_pairs_of_the_family_cross_validation_of_the_training_half(family_cv_pairs):
    """The shipped chain (with its technology terms and the second axle's drag), 5-fold CV by family on
    the training half, pairs by model line. Measured (docs/validation.md): MAPE 6.26 %; UDDS slope 0.87,
    3.73 pp; HWFET slope 1.01, 2.79 pp (105 pairs: the e-tron GT is not paired with the e-tron SUV).
    Both slopes meet the target (0.85-1.15; the UDDS one was 0.84 without the drag); the mean
    differences do NOT (2.5), and are pinned at today's level so that a change cannot make them worse
    unnoticed."""
    cv, s = family_cv_pairs
    assert cv["stats"]["mean_abs_pct"] == pytest.approx(6.26, abs=0.02)
    udds, hwfet = s["epa_udds"], s["epa_hwfet"]
    assert udds["n"] == hwfet["n"] and udds["n"] > 100
    assert udds["slope_met"] is True and hwfet["slope_met"] is True    # 0.873, 1.007
    assert udds["mean_abs_diff_points"] <= 3.7                         # target 2.5 not met (3.54)
    assert hwfet["mean_abs_diff_points"] <= 2.8                        # target 2.5 not met (2.67)


@pytest.fixture(scope="module")
def family_cv_quasi_static():
    from bev_mdo.models import calibrate as cal
    from bev_mdo.models import fleet as fl

    f = fl.read_fleet()
    cycles = fl.resampled_cycles()
    use = cal.usable(f, cycles)
    cv = cal.cross_validate(f, 5, cycles=cycles, use=use, model="quasi_static")
    return cv, cal.cv_pairs(f, cv, use)


@pytest.mark.slow
def test_quasi_static_loss_model_held_out_by_family(family_cv_quasi_static):
    """The default model (``epa2022_quasi_static``: the motor as losses, the two-speed cars shifting, the
    wound-rotor machines' field), 5-fold CV by family as ``bev-mdo calibrate`` runs it. Measured
    (docs/validation.md): MAPE 5.58 % (pinned at <= 6 %; the 6 % target is set by make, 6.70 %: missed);
    pairs UDDS slope 0.869, 3.55 points; HWFET slope
    0.995, 2.65 points. Both slopes meet 0.85-1.15 (UDDS at 0.835 without the field's loss); the
    differences do not (2.5) and are pinned near today's level: a regression fails."""
    cv, s = family_cv_quasi_static
    assert cv["stats"]["mean_abs_pct"] <= 6.0                              # 5.58 (a regression fails)
    udds, hwfet = s["epa_udds"], s["epa_hwfet"]
    assert udds["n"] == hwfet["n"] == 105
    assert udds["slope_met"] is True and hwfet["slope_met"] is True        # 0.869, 0.995
    assert udds["mean_abs_diff_points"] <= 3.7                             # 3.55, target 2.5 not met
    assert hwfet["mean_abs_diff_points"] <= 2.8                            # 2.65, target 2.5 not met


@pytest.fixture(scope="module")
def make_cv_quasi_static():
    from bev_mdo.models import calibrate as cal
    from bev_mdo.models import fleet as fl

    f = fl.read_fleet()
    cycles = fl.resampled_cycles()
    use = cal.usable(f, cycles)
    cv = cal.cross_validate(f, 99, cycles=cycles, groups=[m.lower() for m in f.make], use=use, model="quasi_static")
    return cv, cal.cv_pairs(f, cv, use)


@pytest.mark.slow
def test_quasi_static_loss_model_held_out_by_make(make_cv_quasi_static):
    """The thesis' model with its motor written as losses, the fleet's two-speed cars shifting (eq 2-6)
    and the wound-rotor machines' field, fitted as ``bev-mdo calibrate --model quasi_static`` does, each
    make predicted by a fit that never saw it (9 folds; without BMW no car has a wound rotor and its
    loss stays 0). Measured (docs/validation.md): MAPE 6.70 % over all folds' vehicles, median of the
    folds 5.69 % (target <= 8 %); pairs UDDS slope 0.860, 3.91 points; HWFET slope 0.997, 2.68 points.
    The thesis' model as published: 45.6 %, slopes 1.70 / 1.83, 14.4 / 14.0 points. Both slopes meet
    their target (0.85-1.15; the UDDS one by 0.010, 0.846 under the percentage of the earlier row); the
    differences do not (2.5) and are pinned near today's level: a regression fails."""
    cv, s = make_cv_quasi_static
    assert cv["k"] == 9
    assert cv["stats"]["mean_abs_pct"] <= 7.0
    assert np.median(cv["fold_mape_pct"]) <= 8.0                           # level target met (fold median)
    udds, hwfet = s["epa_udds"], s["epa_hwfet"]
    assert udds["n"] == hwfet["n"] == 105
    assert udds["slope_met"] is True and hwfet["slope_met"] is True        # 0.860, 0.997
    assert udds["mean_abs_diff_points"] <= 4.1                             # 3.91, target 2.5 not met
    assert hwfet["mean_abs_diff_points"] <= 2.85                           # 2.68, target 2.5 not met
