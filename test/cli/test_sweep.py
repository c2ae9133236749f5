"""`bev-mdo sweep` and `bev-mdo compare` in process: one batch, CSV, plots, differences."""
from __future__ import annotations

import csv
import warnings
import json
from pathlib import Path

import pytest

from bev_mdo.cli import main
from bev_mdo.cli.sweep import evaluate_batch, grid, parse_vary, plot_output
from bev_mdo.config import load_config
from bev_mdo.sessions import analyse_baseline


ROOT = Path(__file__).resolve().parents[2]
CONFIG = str(ROOT / "config/leaf_nedc.yaml")


def test_parse_vary_and_full_factorial():
    v = parse_vary(["motor_kw=40:120:9", "gear_ratio=6,8"])
    assert v["motor_kw"].tolist() == [40, 50, 60, 70, 80, 90, 100, 110, 120]
    g = grid(v)
    assert len(g["motor_kw"]) == 18 and g["gear_ratio"][:2].tolist() == [6, 8]
    with pytest.raises(Exception):
        parse_vary(["motor_kw=40:120"])
    with pytest.raises(Exception, match="--vary motor_kw: given twice"):  # the last one used to win
        parse_vary(["motor_kw=40:120:3", "motor_kw=50,60"])
    with pytest.raises(Exception, match="one value between 60 and 150; give N >= 2"):  # 150 was dropped
        parse_vary(["motor_kw=60:150:1"])
    assert parse_vary(["motor_kw=60:60:1"])["motor_kw"].tolist() == [60]
    for spec, typed in (("40:1e400:3", "1e400"), ("40,1e400", "1e400"), ("nan:50:2", "nan")):  # numpy warned,
        with warnings.catch_warnings():  # then the error said motor_kw=nan
            warnings.simplefilter("error")
            with pytest.raises(Exception, match=rf"^motor_kw={typed}: a design value must be a finite number$"):
                parse_vary([f"motor_kw={spec}"])


def test_sweep_writes_csv_and_plots_and_matches_single_evaluations(tmp_path, capsys):
    rc = main(["sweep", CONFIG, "--vary", "motor_kw=40:120:5", "gear_ratio=6:10:3", "--out", str(tmp_path),
               "--transport", "inprocess"])
    assert rc == 0
    rows = list(csv.DictReader(open(tmp_path / "sweep.csv")))
    assert len(rows) == 15
    assert {"motor_kw", "gear_ratio", "battery_kwh", "energy_wh_per_km", "margin.range_km", "feasible"} <= set(rows[0])
    # the 40 kW designs cannot reach 100 km/h in 10 s: infeasible, and marked so
    assert all(r["feasible"] == "False" for r in rows if float(r["motor_kw"]) == 40)
    assert any(r["feasible"] == "True" for r in rows)
    # one row equals a one-design evaluation
    from bev_mdo.api import evaluate

    cfg = load_config(CONFIG)
    r = rows[7]
    one = evaluate.design(cfg, {k: float(r[k]) for k in ("motor_kw", "gear_ratio", "battery_kwh")}, "inprocess")
    assert float(r["energy_wh_per_km"]) == pytest.approx(one["outputs"]["energy_wh_per_km"], rel=1e-9)
    assert (tmp_path / "energy_wh_per_km.png").exists() and (tmp_path / "range_km.png").exists()
    assert "15 designs in one batch" in capsys.readouterr().out


def test_sweep_plot_marks_infeasible_and_draws_the_limit(tmp_path):
    cfg = load_config(CONFIG)
    res = evaluate_batch(cfg, grid(parse_vary(["motor_kw=40:120:5", "gear_ratio=6,8"])), "inprocess")
    fig, ax = plot_output(res, "accel_time_0_100_s", ["motor_kw", "gear_ratio"], tmp_path / "a.png")
    assert ax.get_xlabel() == "motor power (kW)" and ax.get_ylabel() == "0–100 km/h time (s)"
    limit = [l for l in ax.get_lines() if l.get_label().startswith("constraint ≤ 10")]
    assert limit and float(limit[0].get_ydata()[0]) == 10.0
    crosses = [l for l in ax.get_lines() if l.get_marker() == "x" and len(l.get_xdata())]
    assert sum(len(l.get_xdata()) for l in crosses) == int((~res["feasible"]).sum())


def test_sweep_plot_shows_the_configs_baseline(tmp_path):
    cfg = load_config(CONFIG)
    base = analyse_baseline(cfg)
    assert base["name"] == cfg["problem"]["baseline"]["name"]
    res = evaluate_batch(cfg, grid(parse_vary(["motor_kw=40:120:5", "gear_ratio=6,8"])), "inprocess")
    fig, ax = plot_output(res, "energy_wh_per_km", ["motor_kw", "gear_ratio"], tmp_path / "e.png", base)
    # a review: with lines per gear ratio, the star (at its own 7.94:1) read as on a line; its label says its ratio
    star = [l for l in ax.get_lines() if l.get_label() == f"baseline ({base['name']})\ngear_ratio=7.94"]
    assert star and star[0].get_xdata()[0] == 80.0
    assert star[0].get_ydata()[0] == pytest.approx(base["outputs"]["energy_wh_per_km"])
    no_base = dict(cfg, problem={k: v for k, v in cfg["problem"].items() if k != "baseline"})
    assert analyse_baseline(no_base) is None


def test_sweep_plot_spans_the_swept_values_and_its_legend_hides_no_data(tmp_path):
    """`--vary motor_kw=195:212:18` (bounds 150-350) was drawn on 150-350 kW, the data a narrow band, under a
    legend of 24 entries inside the axes; the baseline's star, off the swept range, stretched the y-axis too."""
    import numpy as np

    cfg = load_config(CONFIG)
    base = analyse_baseline(cfg)  # 80 kW: outside 60-70
    res = evaluate_batch(cfg, grid(parse_vary(["motor_kw=60:70:6", "battery_kwh=20:30:21"])), "inprocess")
    fig, ax = plot_output(res, "energy_wh_per_km", ["motor_kw", "battery_kwh"], tmp_path / "e.png", base)
    lo, hi = ax.get_xlim()
    assert 58.0 < lo < 60.0 and 70.0 < hi < 72.0, (lo, hi)
    y = res["outputs"]["energy_wh_per_km"]
    ylo, yhi = ax.get_ylim()
    assert yhi - ylo < 2 * (y.max() - y.min()), "the y-axis is the data's"
    star = [line for line in ax.get_lines() if line.get_label().startswith("baseline")]
    assert len(star) == 1 and len(star[0].get_xdata()) == 0 and "outside the swept range" in star[0].get_label()
    fig.canvas.draw()
    legend, axes = ax.get_legend().get_window_extent(), ax.get_window_extent()
    assert legend.x0 >= axes.x1, "the legend is beside the axes, over no data"
    assert fig.get_window_extent().x1 >= legend.x1, "and within the figure"
    inside = np.array([[xs, ys] for line in ax.get_lines() for xs, ys in line.get_xydata()])
    shown = ax.transData.transform(inside)
    assert not ((shown[:, 0] >= legend.x0) & (shown[:, 0] <= legend.x1) & (shown[:, 1] >= legend.y0)
                & (shown[:, 1] <= legend.y1)).any()


def test_two_vary_flags_both_count(tmp_path, capsys):
    """`--vary motor_kw=... --vary battery_kwh=...`: the second flag replaced the first without a word."""
    assert main(["sweep", CONFIG, "--vary", "motor_kw=60,70", "--vary", "battery_kwh=20,24,28", "--out",
                 str(tmp_path), "--transport", "inprocess", "--no-record", "--no-plots"]) == 0
    assert "6 designs in one batch" in capsys.readouterr().out


def test_sweep_outside_bounds_is_infeasible_and_unknown_names_are_user_errors(tmp_path, capsys):
    assert main(["sweep", CONFIG, "--vary", "motor_kw=10:20:2", "--out", str(tmp_path), "--no-plots",
                 "--transport", "inprocess"]) == 0
    out = capsys.readouterr().out
    assert "0 feasible, 2 infeasible, 0 failed" in out and "note: design 1 (and 1 more): motor_kw = 10 is outside" in out
    assert main(["sweep", CONFIG, "--vary", "wheels=1:2:2", "--out", str(tmp_path), "--transport", "inprocess"]) == 2


@pytest.mark.parametrize("command, argv, named", [
    ("sweep", ["--vary", "motor_kw=nan:120:3"], "motor_kw=nan"),  # its NaN rows were written, exit 0
    ("sweep", ["--vary", "motor_kw=80,inf"], "motor_kw=inf"),
    ("sweep", ["--vary", "motor_kw=80:90:2", "--set", "battery_kwh=nan"], "--set battery_kwh=nan"),
    # the NaN was read as "not given": "must be given in every --design (they are parameters ...)"
    ("compare", ["--design", "motor_kw=nan", "--design", "motor_kw=80"], "--design motor_kw=nan"),
])
def test_a_design_value_that_is_not_finite_is_a_user_error(tmp_path, capsys, command, argv, named):
    out = ["--out", str(tmp_path), "--no-record", "--no-plots"] if command == "sweep" else []
    assert main([command, CONFIG, *argv, *out, "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{named}: a design value must be a finite number" in err[0], err


def test_sweep_from_a_list(tmp_path):
    lst = tmp_path / "designs.csv"
    lst.write_text("motor_kw,gear_ratio,battery_kwh\n80,7.94,24\n74.4782,9.48,20\n")
    assert main(["sweep", CONFIG, "--list", str(lst), "--out", str(tmp_path / "o"), "--no-plots",
                 "--transport", "inprocess"]) == 0
    rows = list(csv.DictReader(open(tmp_path / "o/sweep.csv")))
    assert [float(r["battery_kwh"]) for r in rows] == [24, 20]


@pytest.mark.parametrize("text, said", [
    ("motor_kw,motor_kw\n100,90\n", "the header names 'motor_kw' twice"),  # 90 was swept, 100 dropped
    ("motor_kw,gear_ratio\n100,9,5\n", "design 1 has 3 values for 2 names"),  # "column None ..."
    ("motor_kw,gear_ratio\n100,9\n90\n", "design 2 has 1 values for 2 names"),
    ("motor_kw,gear_ratio\n100,fast\n", "design 1, column 'gear_ratio': not a number: 'fast'"),
    ("motor_kw,gear_ratio\n1_00,9\n", "design 1, column 'motor_kw': not a number: '1_00'"),  # it was 100 kW
    ("motor_kw,gear_ratio\n100,nan\n", "design 1, column 'gear_ratio': must be finite, got nan"),
    ("motor_kw,\n100,9\n", "the header has an empty name"),
    # a column of labels was "design 1, column 'label': not a number: 'leaf'"
    ("label,motor_kw\nleaf,80\n", "column 'label' is not a design variable or parameter; design variables: "
                                   "['motor_kw', 'gear_ratio', 'battery_kwh'], parameters: ['air_density_kg_m3', "),
    ("motor_kw,gear_ratio\n", "no designs"),
    # a misspelt column named no nearest name, as --vary, compare and evaluate --set do
    ("motor_kw,gear_ratoi\n80,8\n", "column 'gear_ratoi' is not a design variable or parameter; did you mean "
                                    "'gear_ratio'? design variables: "),
])
def test_a_malformed_list_is_one_line_naming_the_design_and_column(tmp_path, capsys, text, said):
    lst = tmp_path / "designs.csv"
    lst.write_text(text)
    assert main(["sweep", CONFIG, "--list", str(lst), "--out", str(tmp_path / "o"), "--no-plots", "--no-record",
                 "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"--list {lst}: {said}" in err[0], err


def test_a_listed_design_outside_its_bounds_is_evaluated_infeasible_and_named(tmp_path, capsys):
    """A design outside its bounds was refused by sweep and compare while evaluate took it as given (infeasible,
    with a note): the same design is now the same answer in all three."""
    lst = tmp_path / "designs.csv"
    lst.write_text("motor_kw,gear_ratio\n80,9\n800,9\n")
    assert main(["sweep", CONFIG, "--list", str(lst), "--out", str(tmp_path / "o"), "--no-plots", "--no-record",
                 "--transport", "inprocess"]) == 0
    out = capsys.readouterr().out
    assert ("note: design 2: motor_kw = 800 is outside its bounds [40, 120]: infeasible whatever the constraints "
            "say (evaluated as given)") in out, out
    rows = list(csv.DictReader(open(tmp_path / "o" / "sweep.csv")))
    assert [r["feasible"] for r in rows][1] == "False" and float(rows[1]["motor_kw"]) == 800.0
    assert main(["compare", CONFIG, "--design", "motor_kw=80", "--design", "motor_kw=800", "--json",
                 "--transport", "inprocess"]) == 0
    designs = json.loads(capsys.readouterr().out)["designs"]
    assert designs[1]["feasible"] is False and designs[1]["notes"][0].startswith("motor_kw = 800 is outside its bounds")
    # within the feasibility tolerance (1e-4 of the span): feasible, as evaluate says, but said all the same
    lst.write_text("battery_kwh\n19.9991\n19.5\n")
    assert main(["sweep", CONFIG, "--list", str(lst), "--out", str(tmp_path / "t"), "--no-plots", "--no-record",
                 "--transport", "inprocess"]) == 0
    out = capsys.readouterr().out
    assert "1 feasible, 1 infeasible" in out and ("note: design 1: battery_kwh = 19.9991 is outside its bounds [20, 30] "
                                                   "(evaluated as given)\n") in out, out
    # a value that :g rounds onto its bound read "motor_kw = 120 is outside its bounds [40, 120]" (the second review)
    assert main(["compare", CONFIG, "--design", "motor_kw=120.00001", "--design", "motor_kw=90", "--transport",
                 "inprocess"]) == 0
    assert "note: design 1: motor_kw = 120.00001 is outside its bounds [40, 120]" in capsys.readouterr().out
    assert main(["evaluate", CONFIG, "--set", "motor_kw=800", "--json", "--transport", "inprocess"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["feasible"] is False and report["notes"][0] == designs[1]["notes"][0]
    assert report["outputs"]["energy_wh_per_km"] == pytest.approx(designs[1]["energy_wh_per_km"], rel=1e-9)


def test_a_recorded_design_outside_its_bounds_has_its_distance_past_the_bound_as_violation(tmp_path, capsys):
    """Its record said max violation 0 and infeasible, with no reason; the distance past the bound over the
    bounds' span is its violation (within the feasibility tolerance: feasible, as evaluate says)."""
    from bev_mdo.bag.history import history

    lst = tmp_path / "designs.csv"
    lst.write_text("motor_kw,gear_ratio\n80,9\n800,9\n120.001,9\n")
    assert main(["sweep", CONFIG, "--list", str(lst), "--out", str(tmp_path / "o"), "--no-plots",
                 "--transport", "inprocess"]) == 0
    rows = history(tmp_path / "o" / "bag")
    assert [r["feasible"] for r in rows] == [True, False, True]
    assert rows[0]["max_violation"] == 0.0 and rows[1]["max_violation"] == pytest.approx((800 - 120) / (120 - 40))
    assert rows[2]["max_violation"] == pytest.approx(0.001 / 80)


def test_a_sweep_csv_read_back_as_a_list_gives_the_same_rows(tmp_path, capsys):
    """A user filters sweep.csv (or a Pareto front.csv) and evaluates those rows again: every output column was
    refused as 'not a design variable or parameter'."""
    assert main(["sweep", CONFIG, "--vary", "motor_kw=60:100:3", "--out", str(tmp_path / "a"), "--no-plots",
                 "--no-record", "--transport", "inprocess"]) == 0
    capsys.readouterr()
    assert main(["sweep", CONFIG, "--list", str(tmp_path / "a" / "sweep.csv"), "--out", str(tmp_path / "b"),
                 "--no-plots", "--no-record", "--transport", "inprocess"]) == 0
    err = capsys.readouterr().err
    assert "columns vehicle_mass_kg, energy_wh_per_km," in err and "feasible, ok, error are what a run computes" in err
    first, again = (list(csv.DictReader(open(tmp_path / d / "sweep.csv"))) for d in "ab")
    assert len(again) == 3 and [r["energy_wh_per_km"] for r in again] == [r["energy_wh_per_km"] for r in first]


def test_a_name_mistyped_in_one_compare_design_is_said_unknown(capsys):
    """It was called a parameter with no initial value that must be given in every --design."""
    assert main(["compare", CONFIG, "--design", "motor_kw=100", "--design", "motr_kw=90", "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "unknown names ['motr_kw']; did you mean 'motor_kw'? design variables: ['motor_kw'," in err[0], err


def test_compare_shows_differences_from_the_first_design(capsys):
    rc = main(["compare", CONFIG, "--design", "motor_kw=80,gear_ratio=7.94,battery_kwh=24",
               "--design", "motor_kw=80,gear_ratio=7.94,battery_kwh=30", "--json", "--transport", "inprocess"])
    assert rc == 0
    d = json.loads(capsys.readouterr().out)["designs"]
    assert d[1]["battery_kwh"] - d[0]["battery_kwh"] == 6
    assert d[1]["range_km"] > d[0]["range_km"] and d[1]["vehicle_mass_kg"] > d[0]["vehicle_mass_kg"]
    rc = main(["compare", CONFIG, "--design", "motor_kw=80", "--design", "motor_kw=90", "--transport", "inprocess"])
    out = capsys.readouterr().out
    assert rc == 0 and "Δ 2−1" in out and "+10 (+12.5 %)" in out


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_compare_of_designs_that_all_fail_warns_of_nothing(capsys, sellar_raising):
    """np.nanmax of a row failed in every design put "RuntimeWarning: All-NaN slice encountered" on stderr."""
    cfg = sellar_raising
    rc = main(["compare", str(cfg), "--design", "x=1", "--design", "x=2", "--transport", "inprocess"])
    out, err = capsys.readouterr()
    # no warning; the failures said in one line, exit 1 when every design failed (as sweep; it exited 0, no reason)
    assert rc == 1 and err.startswith("bev-mdo compare: every design failed; the first (design 1): raises: "), err
    assert err.count("\n") == 1
    row = next(line for line in out.splitlines() if line.startswith("│ w "))
    assert row.split("│")[3].strip() == "nan", row


def test_history_of_a_sweep_says_which_designs_failed(tmp_path, capsys, sellar_raising):
    """A failed design (a discipline's NaN) looked like a good one in `history`: nothing said ok or failed."""
    import yaml

    raw = yaml.safe_load(sellar_raising.read_text())
    raw["disciplines"][-1] = {"name": "returns_nan", "class": "bad_disciplines:ReturnsNaN", "options": {"above": 5}}
    sellar_raising.write_text(yaml.safe_dump(raw))
    assert main(["sweep", str(sellar_raising), "--vary", "x=1,9,2", "--out", str(tmp_path / "s"), "--no-plots",
                 "--transport", "inprocess"]) == 0
    capsys.readouterr()
    assert main(["history", str(tmp_path / "s" / "bag"), "--csv", "-"]) == 0
    rows = list(csv.DictReader(capsys.readouterr().out.splitlines()))
    assert [(float(r["design.x"]), r["status"]) for r in rows] == [(1, "ok"), (9, "failed"), (2, "ok")]
    assert main(["history", str(tmp_path / "s" / "bag"), "--width", "80"]) == 0
    table = capsys.readouterr().out
    cells = [[c.strip() for c in line.split("│")] for line in table.splitlines() if line.startswith("│")]
    assert [c[5] for c in cells] == ["ok", "failed", "ok"], table  # iter, objective, violation, feasible, status
    assert "failed: no value (a discipline raised or gave NaN" in table


def test_compare_gives_a_model_parameters_unit(capsys):
    """load_kg varied between two designs had an empty unit column, every other row a unit."""
    rc = main(["compare", CONFIG, "--design", "motor_kw=80,load_kg=75", "--design", "motor_kw=80,load_kg=1000",
               "--transport", "inprocess"])
    row = next(line for line in capsys.readouterr().out.splitlines() if "load_kg" in line)
    assert rc == 0 and row.split("│")[2].strip() == "kg", row


def _wide_gears(tmp_path):
    """leaf_nedc with gear ratios up to 16:1, where the motor's speed limit comes before 100 km/h."""
    import yaml

    raw = yaml.safe_load(Path(CONFIG).read_text())
    raw["problem"]["design_variables"]["gear_ratio"]["upper"] = 16
    p = tmp_path / "wide.yaml"
    p.write_text(yaml.safe_dump(raw))
    return str(p)


def test_compare_and_sweep_say_which_times_are_not_times(tmp_path, capsys):
    """At 15:1 the Leaf cannot reach 100 km/h: its 0-100 km/h time is the continuation value (10 000 s and
    up), which compare showed as '+10240 (+143004 %)' and sweep as a time, with no word (evaluate had one)."""
    cfg = _wide_gears(tmp_path)
    assert main(["compare", cfg, "--design", "gear_ratio=8", "--design", "gear_ratio=15", "--transport", "inprocess"]) == 0
    notes = [line for line in capsys.readouterr().out.splitlines() if line.startswith("note:")]
    # design 2 cannot follow the NEDC either (it is infeasible, and says so first)
    assert len(notes) == 2 and notes[0].startswith("note: design 2: the design cannot follow the cycle nedc"), notes
    assert notes[1].startswith("note: design 2: the design cannot reach 100 km/h"), notes
    assert main(["compare", cfg, "--design", "gear_ratio=8", "--design", "gear_ratio=15", "--json",
                 "--transport", "inprocess"]) == 0
    d = json.loads(capsys.readouterr().out)["designs"]
    assert "notes" not in d[0] and "continuation value" in d[1]["notes"][1]
    assert main(["sweep", cfg, "--vary", "gear_ratio=6:15:4", "--out", str(tmp_path / "s"), "--no-plots",
                 "--no-record", "--transport", "inprocess"]) == 0
    rows = list(csv.DictReader(open(tmp_path / "s" / "sweep.csv")))
    slow = sum(float(r["accel_time_0_100_s"]) >= 10000 for r in rows)
    notes = [line for line in capsys.readouterr().out.splitlines() if line.startswith("note:")]
    assert slow == 1 and notes == [f"note: accel_time_0_100_s: {slow} of 4 designs at or above 10000 (from there up "
                                   "the value marks a design that cannot reach 100 km/h): not values of the quantity",
                                   "note: 2 of 4 designs cannot follow the drive cycle (their motor falls short of the "
                                   "drive force or over its speed limit): infeasible"]


def test_compare_percent_has_the_sign_of_the_difference_for_a_negative_quantity(capsys):
    """The aerostructure displacement is negative (-745 at the start): a rise of +8 was shown
    '+7.99663 (-1.1 %)'; the percentage is now of |design 1|, so it has the difference's sign."""
    aero = Path(__file__).resolve().parents[2] / "examples" / "aerostructure" / "aerostructure_mdf.yaml"
    rc = main(["compare", str(aero), "--design", "thick_airfoils=15,thick_panels=3,sweep=25",
               "--design", "thick_airfoils=5,thick_panels=3.2255892255892404,sweep=24.99326599326595",
               "--transport", "inprocess"])
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if "displ" in line)
    assert rc == 0 and "+7.99663 (+1.1 %)" in row


def test_sweep_bag_records_the_normalised_violation_and_the_configs_tolerance(tmp_path, capsys):
    """The sweep's bag recorded the largest violation in the constraints' own units (61.8 for 61.8 km
    short of range beside seconds and rad/s), which history and report show as an optimisation's
    normalised one; and a sweep judged feasibility with the default tolerance, not the config's."""
    import yaml

    from bev_mdo.bag.history import history

    raw = yaml.safe_load(Path(CONFIG).read_text())
    raw["optimizer"]["feasibility_tolerance"] = 1e-9
    raw["problem"]["constraints"]["accel_time_0_100_s"] = {"upper": 9.856 * (1 - 1e-6)}  # 80 kW, 8:1
    cfg = tmp_path / "tight.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    assert main(["sweep", str(cfg), "--vary", "motor_kw=40,80", "--out", str(tmp_path / "s"), "--no-plots",
                 "--transport", "inprocess"]) == 0
    capsys.readouterr()
    recs = history(tmp_path / "s" / "bag")
    lim = raw["problem"]["constraints"]["accel_time_0_100_s"]["upper"]
    for r in recs:
        assert r["max_violation"] == pytest.approx((r["constraints"]["accel_time_0_100_s"] - lim) / lim, rel=1e-9)
    assert [r["feasible"] for r in recs] == [False, False]  # 80 kW is 1e-6 over, beyond a tolerance of 1e-9


@pytest.mark.parametrize("argv", [["--vary", "motor_kw=40:120:3", "--seed", "5"], ["--vary", "motor_kw=40:120:3",
                                  "--samples", "7"]])
def test_seed_and_samples_without_doe_are_refused_not_ignored(tmp_path, capsys, argv):
    assert main(["sweep", CONFIG, *argv, "--out", str(tmp_path / "o"), "--transport", "inprocess"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--samples and --seed go with --doe" in err[0], err
    assert not (tmp_path / "o").exists()


def test_a_sweep_stopped_while_its_bag_is_written_is_said_to_be_part_of_it(tmp_path, capsys, monkeypatch):
    """A SIGTERM while the bag was written kept 3,103 of 20,000 designs, and history, report ('design 347 of
    3103') and resume took it for the whole sweep; a SIGTERM while sweep.csv was written left part of its
    rows under its final name."""
    from bev_mdo.api import runbag

    written = runbag.InProcessBag.__call__

    def stops_after_three(self, rec):
        if rec["iteration"] == 3:
            raise KeyboardInterrupt
        written(self, rec)

    monkeypatch.setattr(runbag.InProcessBag, "__call__", stops_after_three)
    out = tmp_path / "s"
    assert main(["sweep", CONFIG, "--vary", "motor_kw=60:120:7", "--out", str(out), "--no-plots",
                 "--transport", "inprocess"]) == 130
    monkeypatch.undo()
    assert not (out / "sweep.csv").exists()  # the bag first; the CSV is written whole or not at all
    capsys.readouterr()
    assert main(["history", str(out)]) == 0
    assert "the sweep's bag holds 3 of its 7 designs (it was stopped while written)" in capsys.readouterr().err
    from bev_mdo.cli.sweep import write_csv

    res = evaluate_batch(load_config(CONFIG), grid(parse_vary(["motor_kw=70,90"])), "inprocess")
    write_csv(tmp_path / "w.csv", res)
    assert len(list(csv.DictReader(open(tmp_path / "w.csv")))) == 2 and not (tmp_path / "w.csv.part").exists()


def test_a_batch_over_ros_is_sent_in_chunks_with_the_results_of_one_batch(monkeypatch):
    """Over ROS one request of 100,000 designs outlasted ros.timeout_s (5 s): it was re-sent to a node still
    busy with it, and one longer than the retry budget failed every design (a user trial). The batch now goes
    in chunks sized to answer well within ros.timeout_s; the results are those of one in-process batch."""
    import contextlib
    import types

    import numpy as np

    from bev_mdo.api import evaluate
    from bev_mdo.api.doe import sample
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    from bev_mdo.config import RunConfig

    cfg = RunConfig.of(load_config(CONFIG))
    sizes: list[int] = []

    class OverRos:  # what Evaluating yields over ROS: its orchestrator (``inner``) has ros.timeout_s
        def __init__(self):
            self._ev = InProcessEvaluator(cfg.disciplines)
            self.specs, self.inner = self._ev.specs, types.SimpleNamespace(timeout_s=5.0)

        def evaluate(self, calls, partials=False):
            sizes.extend(len(next(iter(batch.values()))) for _, batch in calls)
            return self._ev.evaluate(calls, partials=partials)

    n = 20_000
    bounds = {d.name: (d.lower, d.upper) for d in cfg.problem.design_variables}
    designs = sample("lhs", bounds, n, seed=3)
    whole = evaluate.batch(cfg, designs, "inprocess")
    monkeypatch.setattr(evaluate, "Evaluating", lambda *a, **k: contextlib.nullcontext(OverRos()))
    chunked = evaluate.batch(cfg, designs, "ros")
    assert sizes and max(sizes) < n and sum(sizes) == n * len(cfg.names)  # several requests, every design once
    for k, v in whole["outputs"].items():
        np.testing.assert_allclose(chunked["outputs"][k], v, rtol=1e-12, equal_nan=True, err_msg=k)
    assert (chunked["ok"] == whole["ok"]).all() and chunked["errors"] == whole["errors"]


def test_compare_gives_no_percentage_of_a_margin_output(capsys):
    """A pareto trial: compare showed the topology model's drive_torque_margin_nm change as '+13327.1 %' (of a
    margin near zero); a margin, a constraint's or an output's, gets its difference alone."""
    topo = Path(__file__).resolve().parents[2] / "config" / "topologies_artemis.yaml"
    rc = main(["compare", str(topo), "--design", "motor_kw=80,gear_ratio=8,battery_kwh=24", "--design",
               "motor_kw=120,gear_ratio=8,battery_kwh=24", "--transport", "inprocess"])
    out = capsys.readouterr().out
    row = next(line for line in out.splitlines() if line.startswith("│ drive_torque_margin_nm"))
    assert rc == 0 and "%" not in row, row
    assert "%" in next(line for line in out.splitlines() if line.startswith("│ vehicle_mass_kg"))


def test_one_design_is_said_in_the_singular(tmp_path, capsys):
    assert main(["sweep", CONFIG, "--vary", "motor_kw=80:80:1", "--transport", "inprocess", "--no-record",
                 "--out", str(tmp_path / "o"), "--no-plots"]) == 0
    assert "1 design in one batch (inprocess)" in capsys.readouterr().out


def test_a_sweep_whose_every_design_fails_exits_1_and_says_the_first_reason(tmp_path, capsys, sellar_raising):
    """A malformed-files trial: 8 designs, 8 failed (a discipline raised), exit 0, the reason in sweep.csv alone."""
    rc = main(["sweep", str(sellar_raising), "--vary", "x=1,2", "--out", str(tmp_path / "s"), "--no-plots",
               "--no-record", "--transport", "inprocess"])
    out, err = capsys.readouterr()
    assert rc == 1 and "0 feasible, 2 infeasible, 2 failed" in out
    assert err.startswith("bev-mdo sweep: every design failed; the first (design 1): raises: ") and err.endswith(
        "(sweep.csv: error)\n") and err.count("\n") == 1, err
    assert (tmp_path / "s" / "sweep.csv").is_file()  # what was done is written
