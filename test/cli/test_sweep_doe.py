"""`bev-mdo sweep --doe lhs|sobol|halton|full`: designs over the bounds (with --bound overrides),
one batch, CSV, plots and a bag that `history` reads from the output folder."""
from __future__ import annotations

import csv

import numpy as np
import pytest
import yaml

from bev_mdo.cli import main
from bev_mdo.testing import REPO

CONFIG = REPO / "config" / "leaf_nedc.yaml"
SWEEP = ("sweep", str(CONFIG), "--transport", "inprocess")  # in process
BOUNDS = {"motor_kw": (40, 120), "gear_ratio": (1, 11), "battery_kwh": (20, 30)}


def _rows(path):
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _column(rows, name):
    return np.array([float(r[name]) for r in rows])


def test_lhs_fills_every_stratum_of_every_variable_once_and_records_a_bag(tmp_path, capsys):
    out = tmp_path / "lhs"
    assert main([*SWEEP, "--doe", "lhs", "--samples", "40", "--seed", "3", "--out", str(out),
                 "--no-plots"]) == 0
    rows = _rows(out / "sweep.csv")
    assert len(rows) == 40
    for name, (lo, hi) in BOUNDS.items():
        x = _column(rows, name)
        strata = np.floor((x - lo) / (hi - lo) * 40).astype(int)
        assert sorted(strata) == list(range(40)), name
    capsys.readouterr()
    # history finds the bag inside the output folder; one record per design, in order
    assert main(["history", str(out), "--csv", "-"]) == 0
    records = list(csv.DictReader(capsys.readouterr().out.splitlines()))
    assert [int(r["iteration"]) for r in records] == list(range(40))
    for r, row in zip(records, rows):
        assert float(r["design.motor_kw"]) == pytest.approx(float(row["motor_kw"]), rel=1e-9)
        assert float(r["objective"]) == pytest.approx(float(row["energy_wh_per_km"]), rel=1e-9)


def test_sobol_with_bound_override_stays_inside_and_the_bag_records_the_effective_bounds(tmp_path):
    out = tmp_path / "sobol"
    assert main([*SWEEP, "--doe", "sobol", "--samples", "32", "--bound", "motor_kw=60:70",
                 "--set", "battery_kwh=22", "--out", str(out), "--no-plots"]) == 0
    rows = _rows(out / "sweep.csv")
    motor, gear, battery = (_column(rows, k) for k in ("motor_kw", "gear_ratio", "battery_kwh"))
    assert len(rows) == 32 and motor.min() >= 60 and motor.max() <= 70
    assert (battery == 22).all() and gear.min() >= 1 and gear.max() <= 11
    # a scrambled Sobol' sequence of 2^5 points puts 16 in each half of every variable's range
    assert ((motor < 65).sum(), (gear < 6).sum()) == (16, 16)
    from bev_mdo.bag.reader import open_bag, read_config

    recorded = yaml.safe_load(read_config(open_bag(out / "bag")))
    assert recorded["problem"]["design_variables"]["motor_kw"]["lower"] == 60
    assert recorded["problem"]["design_variables"]["motor_kw"]["upper"] == 70


def test_report_finds_the_bag_inside_the_output_folder(tmp_path, capsys):
    out = tmp_path / "run"
    assert main([*SWEEP, "--doe", "halton", "--samples", "8", "--out", str(out), "--no-plots"]) == 0
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    assert (out / "bag" / "report.md").is_file()
    assert str(out / "bag" / "report.md") in capsys.readouterr().out


def test_full_factorial_and_halton_with_plots(tmp_path):
    out = tmp_path / "full"
    assert main([*SWEEP, "--doe", "full", "--samples", "3", "--out", str(out), "--no-record"]) == 0
    rows = _rows(out / "sweep.csv")
    assert len(rows) == 27
    assert sorted(set(_column(rows, "gear_ratio"))) == [1.0, 6.0, 11.0]
    assert (out / "energy_wh_per_km.png").stat().st_size > 1000 and not (out / "bag").exists()
    out = tmp_path / "halton"
    assert main([*SWEEP, "--doe", "halton", "--samples", "20", "--out", str(out)]) == 0
    assert len(_rows(out / "sweep.csv")) == 20 and (out / "range_km.png").stat().st_size > 1000


@pytest.mark.parametrize("argv, message", [
    (["--doe", "sobol", "--samples", "30"], "must be a power of 2"),
    (["--doe", "lhs", "--vary", "motor_kw=40:120:3"], "give one of"),
    (["--doe", "lhs", "--bound", "motor_kv=40:100"], "did you mean 'motor_kw'"),
])
def test_bad_doe_input_is_one_line_exit_2(tmp_path, capsys, argv, message):
    assert main([*SWEEP, *argv, "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err


def test_report_and_resume_of_a_sweep_start_from_its_best_design_not_its_last(tmp_path, capsys):
    """A sweep's records are in no order: its report heads with, and resume starts from, the best feasible
    design (here the second of four; the last is infeasible)."""
    from bev_mdo.cli.resume import resume_point

    lst = tmp_path / "designs.csv"
    lst.write_text("motor_kw,gear_ratio,battery_kwh\n80,7.94,24\n74.4782,9.48,20\n90,8,22\n60,5,30\n")
    out = tmp_path / "o"
    assert main(["sweep", str(CONFIG), "--list", str(lst), "--out", str(out), "--no-plots",
                 "--transport", "inprocess"]) == 0
    checks: dict = {}
    _, design, iteration = resume_point(str(out / "bag"), checks=checks)
    assert (iteration, design["battery_kwh"]) == (1, 20.0)
    assert checks["sweep"] == "the sweep's best design (design 2 of 4, iteration 1 in history)"
    capsys.readouterr()
    assert main(["report", str(out)]) == 0
    md = (out / "bag" / "report.md").read_text()
    assert "## The sweep's best design (design 2 of 4, iteration 1 in history)" in md and "## Final iterate" not in md
    assert "| battery_kwh | kWh | 20 |" in md


def test_a_sweeps_headline_is_the_best_feasible_else_the_least_violated_failed_last():
    from bev_mdo.bag.history import headline

    def rec(objective, violation, feasible):
        return {"formulation": "doe", "objective": objective, "max_violation": violation, "feasible": feasible}

    rows = [rec(5.0, 0.0, True), rec(3.0, 0.0, True), rec(1.0, 0.2, False), rec(9.0, 0.0, True)]
    assert (headline(rows), headline(rows, -1.0)) == (1, 3)
    rows = [rec(1.0, float("nan"), False), rec(2.0, 0.3, False), rec(0.5, 0.1, False)]
    assert headline(rows) == 2
    rows = rows[::-1]
    assert headline(rows) == 0
    assert headline([{**r, "formulation": "MDF"} for r in rows]) == 2  # an optimisation: its last record


def test_a_failed_design_is_recorded_without_values_even_where_the_mda_kept_one(tmp_path, capsys):
    # A 2,600 kWh battery makes a 21.7 t car (past the models' 20 t): the MDA keeps its cost and motor speed,
    # which do not depend on the failed energy, but the bag's record says the point has no values
    # (IterationRecord.msg: NaN where the point failed); a user trial saw its cost as the objective.
    out = tmp_path / "failed"
    assert main(["sweep", str(REPO / "config" / "leaf_nedc.yaml"), "--objective", "powertrain_cost_usd",
                 "--vary", "battery_kwh=24,2600", "--set", "motor_kw=80", "gear_ratio=8",
                 "--transport",
                 "inprocess", "--out", str(out), "--no-plots"]) == 0
    rows = _rows(out / "sweep.csv")
    assert [r["ok"] for r in rows] == ["True", "False"] and float(rows[1]["powertrain_cost_usd"]) > 0  # kept
    capsys.readouterr()
    assert main(["history", str(out), "--csv", "-"]) == 0
    records = list(csv.DictReader(capsys.readouterr().out.splitlines()))
    assert float(records[0]["objective"]) > 0 and records[1]["feasible"] == "False"
    assert np.isnan(float(records[1]["objective"])) and np.isnan(float(records[1]["max_violation"]))
