"""The reference columns of a validation: the 3-constant baseline (held out by family) and FASTSim's
shipped results, scored on the same rows."""
import numpy as np
import pytest

from bev_mdo.models import baselines as bl
from bev_mdo.models import calibrate as cal
from bev_mdo.models import fleet as fl


@pytest.fixture(scope="module")
def fleet():
    return fl.read_fleet()


def test_folds_are_the_calibration_split(fleet):
    """The baseline is held out on the same family folds as the chain's cross-validation."""
    use = ~fleet.outlier
    folds = bl.family_folds(fleet, use)
    assert (folds == fl.group_folds(fleet.family(), bl.FOLDS)[0]).all()
    fam = np.array(fleet.family())
    for g in set(fam):  # a family never split
        assert len(set(folds[fam == g])) == 1


def test_baseline_is_fitted_only_on_training_folds(fleet):
    """Changing a row's measured energy does not move its own prediction nor any of its fold, and
    does move the other folds' (so the check can fail)."""
    use = ~fleet.outlier
    folds = bl.family_folds(fleet, use)
    before = bl.three_constant_cv(fleet, use)
    i = 0
    for c in fl.CYCLES:
        fleet.measured[c] = fleet.measured[c].copy()
        fleet.measured[c][i] *= 1.5
    try:
        after = bl.three_constant_cv(fleet, use)
    finally:
        for c in fl.CYCLES:
            fleet.measured[c][i] /= 1.5
    same = folds == folds[i]
    for c in fl.CYCLES:
        assert np.array_equal(after[c][same], before[c][same])
        assert not np.allclose(after[c][~same], before[c][~same], rtol=1e-6, atol=0)


def test_baseline_is_a_plus_b_mass_plus_c_road_load(fleet):
    """A fleet whose energies are exactly a + b M + c W_road is predicted exactly out of fold."""
    use = ~fleet.outlier
    work = bl.road_load_wh_per_km(fleet)
    saved = {c: fleet.measured[c] for c in fl.CYCLES}
    try:
        for c in fl.CYCLES:
            fleet.measured[c] = 20.0 + 0.03 * fleet.test_mass_kg + 1.4 * work[c]
        pred = bl.three_constant_cv(fleet, use)
        for c in fl.CYCLES:
            np.testing.assert_allclose(pred[c], fleet.measured[c], rtol=1e-9)
    finally:
        fleet.measured.update(saved)


def test_road_load_work_is_the_force_integral(fleet):
    """The work per km from the cycle's speed moments equals the coast-down force integrated over
    the cycle (models/road_load.py, acting while moving) per distance; 1 N over 1 km is 1/3.6 Wh."""
    from bev_mdo.models import road_load as rl
    from bev_mdo.models.cycles import quadrature

    cycles = fl.resampled_cycles()
    work = bl.road_load_wh_per_km(fleet, cycles)
    p = fl.fleet_params(fleet)
    for c, r in cycles.items():
        v, _, _, w = quadrature(r)
        w = np.broadcast_to(w, v.shape)
        f = rl.road_load_n(p, v[:, None], fleet.test_mass_kg[None, :])
        np.testing.assert_allclose(work[c], (w[:, None] * f * v[:, None]).sum(0) / (w * v).sum() / 3.6, rtol=1e-9)
        # road-load work is dissipated, so it all comes from the wall: below every measured energy
        assert (work[c] > 0).all() and (work[c] < fleet.measured[c]).all()


def test_fastsim_results_match_the_fleet_rows(fleet, tmp_path):
    e = bl.read_fastsim(fleet)
    for c in fl.CYCLES:
        assert np.isfinite(e[c]).all()  # every row of the shipped fleet, trace met
        ratio = e[c] / fleet.measured[c]
        assert 0.6 < ratio.min() and ratio.max() < 1.6  # same quantity (wall energy), same units
    assert bl.read_fastsim(fleet, tmp_path / "absent.csv") is None
    other = fl.read_fleet()
    other.model[0] = "Not Run By FASTSim"
    assert np.isnan(bl.read_fastsim(other)["epa_udds"][0]) and np.isfinite(bl.read_fastsim(other)["epa_udds"][1])


def test_fastsim_figures_follow_the_vehicle_not_the_row_number(tmp_path):
    """A reversed or partial copy of the shipped file lost FASTSim's figures: rows were matched by their
    row number ('unavailable: FASTSim was not run on this fleet file'; a 4-make subset: 23 of 36 rows)."""
    import csv

    with fl.DEFAULT_FLEET.open(newline="") as f:
        rows = list(csv.reader(f))
    shipped = bl.read_fastsim(fl.read_fleet())
    for name, body in (("reversed.csv", rows[:0:-1]), ("tesla.csv", [r for r in rows[1:] if r[0] == "Tesla"])):
        path = tmp_path / name
        with path.open("w", newline="") as f:
            csv.writer(f).writerows([rows[0], *body])
        copy = fl.read_fleet(path)
        got = bl.read_fastsim(copy)
        for c in fl.CYCLES:
            want = [shipped[c][int(r) - 2] for r in [rows.index(b) + 1 for b in body]]
            assert np.isfinite(got[c]).all() and got[c] == pytest.approx(want, rel=0, abs=0)


@pytest.mark.parametrize("column, value", [("road_load_c_n_per_m2_s2", 0.2), ("test_mass_kg", 1900.0),
                                           ("rated_power_kw", 150.0), ("drive", "F")])
def test_a_row_fastsim_was_not_run_on_gets_no_fastsim_figure(column, value):
    """A user's copy of the shipped fleet file with one row's input changed (same row, make and model)
    was scored against FASTSim's figure for the original row."""
    edited = fl.read_fleet()
    getattr(edited, column)[3] = value
    e = bl.read_fastsim(edited)
    for c in fl.CYCLES:
        assert np.isnan(e[c][3]) and np.isfinite(np.delete(e[c], 3)).all()


def test_reference_table_scores_every_column_on_the_same_rows(fleet):
    use = ~fleet.outlier
    base = bl.three_constant_cv(fleet, use)
    hole = {c: base[c].copy() for c in fl.CYCLES}
    hole["epa_udds"][3] = np.nan  # a column without a prediction for row 3 removes row 3 for all
    t = bl.reference_table(fleet, {"measured": dict(fleet.measured), "baseline3": base, "holed": hole})
    assert t["udds"]["rows"] == len(fleet) - 1 and t["hwfet"]["rows"] == len(fleet)
    for c in ("udds", "hwfet"):
        assert t[c]["measured"]["mape_pct"] == 0 and t[c]["measured"]["pair_slope"] == pytest.approx(1.0)
        assert t[c]["measured"]["pair_mad_points"] == 0
    assert t["hwfet"]["holed"] == t["hwfet"]["baseline3"]
    assert t["udds"]["pairs"] < t["hwfet"]["pairs"]  # the pairs of row 3 dropped on UDDS only


def test_the_benchmark_table_has_every_model_column():
    """bench/bench_validate.py's accuracy table (rendered into the docs) has a row for every energy
    model validate offers (the quasi-static one also with the thesis' own constants), the baseline and FASTSim, each with the held-out MAPE and pair metrics."""
    import json
    from pathlib import Path

    doc = json.loads((Path(__file__).resolve().parents[2] / "bench" / "results" / "bench_validate.json").read_text())
    (table,) = doc["tables"]
    names = [r[0] for r in table["rows"]]
    assert names == [*fl.ENERGY_MODELS, "quasi_static_thesis", "baseline3", "fastsim"]
    assert table["columns"][2:] == ["UDDS+HWFET MAPE %"] + [f"{c} {m}" for c in ("UDDS", "HWFET") for m in (
        "MAPE %", "pair slope", "pair mean abs diff (points)")]
    for c in ("udds", "hwfet"):
        for name in names:
            cell = doc["held_out"][c][name]
            assert all(isinstance(cell[k], float) for k in ("mape_pct", "pair_slope", "pair_mad_points"))


def test_no_baseline_from_fewer_rows_than_constants(fleet):
    """Three constants from two training rows is no fit: those rows are not predicted (lstsq had returned
    its minimum-norm answer, shown as the baseline's MAPE)."""
    fam = np.array(fleet.family())
    first, second = sorted(set(fam))[:2]
    use = np.zeros(len(fleet), bool)
    use[np.flatnonzero(fam == first)[:2]] = use[np.flatnonzero(fam == second)[:2]] = True
    pred = bl.three_constant_cv(fleet, use)
    assert all(np.isnan(pred[c]).all() for c in fl.CYCLES)
    use[fam == second] = True  # all six rows of the second family (two masses, three road loads)
    pred = bl.three_constant_cv(fleet, use)
    assert all(np.isfinite(pred[c][use & (fam == first)]).all() for c in fl.CYCLES)
