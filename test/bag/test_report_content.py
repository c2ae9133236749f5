"""Report content without looking at pixels: units in axis labels, bounds and limits drawn,
infeasible iterates marked, baseline shown, the answers (active constraints, bounds) named.

Two in-process runs write real bags (``optimize --transport inprocess --bag``): the default problem
(feasible; ends on the motor-speed and 0-100 km/h limits with the battery on its lower bound) and the
WLTC problem with a 250 km range (infeasible; the battery on its upper bound blocks the range).
"""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import matplotlib
import pytest
import yaml

matplotlib.use("Agg")


ROOT = Path(__file__).resolve().parents[2]


def _run(tmp: Path, config_path: Path, name: str) -> tuple[int, Path, dict]:
    import contextlib
    import io

    from bev_mdo.cli import main

    bag = tmp / name
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["optimize", str(config_path), "--transport", "inprocess", "--bag", str(bag), "--json", "--quiet"])
    return rc, bag, json.loads(buf.getvalue())


@pytest.fixture(scope="module")
def feasible_run(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("feasible"), ROOT / "config/leaf_nedc.yaml", "leaf")


@pytest.fixture(scope="module")
def infeasible_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("infeasible")
    cfg = yaml.safe_load((ROOT / "config/leaf_nedc.yaml").read_text())
    cfg["cycle"]["name"] = "wltc_class3"
    cfg["problem"]["constraints"]["range_km"] = {"lower": 250}
    path = tmp / "wltc250.yaml"
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return _run(tmp, path, "wltc250")


def test_feasible_run_names_its_active_constraints_and_bounds(feasible_run):
    rc, bag, out = feasible_run
    assert rc == 0
    act = out["active"]
    assert {(a["name"], a["kind"]) for a in act["active_constraints"]} == {
        ("motor_speed_max_rad_s", "upper"), ("accel_time_0_100_s", "upper")}
    assert [(b["name"], b["kind"]) for b in act["bounds"]] == [("battery_kwh", "lower")]
    assert act["violated"] == []
    assert all(a["unit"] for a in act["active_constraints"])  # rad/s, s


def test_infeasible_run_says_what_is_violated_and_which_bound_blocks(infeasible_run):
    rc, bag, out = infeasible_run
    assert rc == 1
    act = out["active"]
    viol = {v["name"]: v for v in act["violated"]}
    assert "range_km" in viol and viol["range_km"]["violation"] > 0
    assert viol["range_km"]["unit"] == "km"
    blockers = [(b["variable"], b["bound"]) for b in viol["range_km"]["blocked_by"]]
    assert ("battery_kwh", "upper") in blockers
    assert any("battery_kwh on its upper bound" in line for line in act["lines"])


def test_the_answers_are_stored_in_the_in_process_bag(infeasible_run):
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.history import read_answers

    _, bag, out = infeasible_run
    stored = read_answers(open_bag(bag))
    assert stored is not None and stored["lines"] == out["active"]["lines"]


def test_report_markdown_names_the_answers_mass_and_cost(infeasible_run, tmp_path):
    from bev_mdo.bag.report import report

    _, bag, out = infeasible_run
    paths = report(bag, tmp_path)
    md = (tmp_path / "report.md").read_text()
    # optimize's 'iterations' count the records after the start (record 0): the report counts records
    n = out["iterations"]
    assert f"- {n + 1} records (iterations 0-{n})," in md and f"{n + 1} iterations" not in md
    assert "## Why the end point is infeasible" in md
    assert "blocked by battery_kwh on its upper bound" in md
    assert "| vehicle_mass_kg | kg |" in md and "| powertrain_cost_usd | USD |" in md
    assert {p.name for p in paths} >= {"convergence.png", "design.png", "constraints.png", "report.md"}


def test_a_report_parses_the_stored_config_once(feasible_run, tmp_path, monkeypatch):
    """report() parsed the bag's stored config for the records (design names, record window), again
    for the verifier's key file, for the report's own config and for the objective's sense (twice):
    once now, every reader taking it from the opened bag (``Bag.stored_config``)."""
    from bev_mdo.bag.reader import open_bag, read_config
    from bev_mdo.bag.report import report

    _, bag, _ = feasible_run
    stored = read_config(open_bag(bag))
    real, parsed = yaml.SafeLoader.__init__, []

    def counting(self, stream, *args, **kwargs):  # every safe YAML parse: yaml.safe_load and yamlload.load_yaml
        parsed.append(stream == stored)
        real(self, stream, *args, **kwargs)

    monkeypatch.setattr(yaml.SafeLoader, "__init__", counting)
    report(bag, tmp_path)
    assert stored and parsed.count(True) == 1
    md = (tmp_path / "report.md").read_text()  # the stored config loaded from that parse: the iterate analysed
    assert "| vehicle_mass_kg | kg |" in md and "## Configuration (as recorded)" in md


def _figures(bag):
    from bev_mdo.bag import report as rep
    from bev_mdo.bag.history import history
    from bev_mdo.bag.reader import open_bag

    b = open_bag(bag)
    rows = history(b)
    config, problem = rep._context(b)
    base = rep._baseline(config, problem)
    return rows, problem, base, rep, rep._units(config)  # the units the disciplines declare


def test_design_plot_has_units_bounds_baseline_and_marks_infeasible(infeasible_run, tmp_path):
    rows, problem, base, rep, units = _figures(infeasible_run[1])
    fig = rep._plot_design(rows, tmp_path / "d.png", problem, base, units)
    axes = fig.axes
    assert [a.get_ylabel() for a in axes] == ["motor power (kW)", "gear ratio (–)", "battery capacity (kWh)"]
    for ax, d in zip(axes, problem.design_variables):
        ys = {round(float(l.get_ydata()[0]), 9) for l in ax.get_lines() if l.get_linestyle() == "--"}
        assert {d.lower, d.upper} <= ys, f"bounds of {d.name} not drawn"
        labels = [l.get_label() for l in ax.get_lines()]
        assert "infeasible iterate" in labels and "baseline (Leaf (80 kW, 7.94:1, 24 kWh))" in labels
    # the battery sits on its upper bound at the end, inside the drawn limits
    battery = axes[2]
    assert battery.get_ylim()[1] >= 30


def test_constraint_plot_draws_limits_with_units(feasible_run, tmp_path):
    rows, problem, base, rep, units = _figures(feasible_run[1])
    fig = rep._plot_constraints(rows, tmp_path / "c.png", problem, base, units)
    by_label = {a.get_ylabel(): a for a in fig.axes}
    assert set(by_label) == {"range (km)", "max motor speed (rad/s)", "0–100 km/h time (s)"}
    limits = {round(float(l.get_ydata()[0]), 6) for a in fig.axes for l in a.get_lines() if l.get_linestyle() == "--"}
    assert {170.0, 1000.0, 10.0} <= limits


def test_convergence_plot_labels_the_objective_with_its_unit(feasible_run, tmp_path):
    rows, problem, base, rep, units = _figures(feasible_run[1])
    fig = rep._plot_convergence(rows, tmp_path / "v.png", base, units)
    assert fig.axes[0].get_ylabel() == "battery energy (Wh/km)"
    assert "baseline (Leaf (80 kW, 7.94:1, 24 kWh))" in [l.get_label() for l in fig.axes[0].get_lines()]
    markers = [l for l in fig.axes[0].get_lines() if l.get_label() == "infeasible iterate"]
    assert markers and len(markers[0].get_xdata()) == sum(not r["feasible"] for r in rows)


def test_history_of_a_bag_without_iterations_says_what_it_holds(tmp_path, capsys):
    from bev_mdo.bag.writer import BagWriter
    from bev_mdo.cli import main

    with BagWriter(tmp_path / "empty", metadata={"run_id": "x"}) as w:
        w.add_topic("/bev_mdo/iteration", "bev_mdo_msgs/msg/IterationRecord")
    rc = main(["history", str(tmp_path / "empty")])
    err = capsys.readouterr().err
    # it said "its 0 messages are iteration records, none of them kept": the topic is declared, nothing on it
    assert rc == 1 and err.endswith("empty: no iteration records; it holds no messages at all\n")


def test_history_table_fits_the_width_and_names_what_it_left_out(feasible_run):
    import io

    from bev_mdo.bag.history import flat_rows, history
    from bev_mdo.cli.history import print_table

    rows = flat_rows(history(feasible_run[1]))
    for width in (80, 120, 200):
        buf = io.StringIO()
        print_table(rows, width=width, file=buf)
        lines = buf.getvalue().splitlines()
        assert max(len(l) for l in lines) <= width
        assert any("objective" in l for l in lines)
    buf = io.StringIO()
    print_table(rows, width=80, file=buf)
    assert "--csv FILE has all" in " ".join(buf.getvalue().split())  # (the caption may wrap)
    # each shown column keeps its full values (no column shrunk to nothing)
    assert "98.4312" in buf.getvalue()  # the NEDC optimum (exact cycle integration)


def test_history_refuses_a_width_no_table_fits(feasible_run, capsys):
    """--width 0 printed a blank line and exited 0."""
    from bev_mdo.cli import main

    assert main(["history", str(feasible_run[1]), "--width", "0"]) == 2
    assert "--width 0: the table needs at least 40 characters" in capsys.readouterr().err


def test_report_names_the_runs_result(tmp_path):
    """A converged run's result is its last iterate unless an earlier one is better and no more violated
    (driver.pick_result). Golinski with COBYLA converges at iteration 52 (violation 3e-15); the report read
    the records without knowing the run converged and said 'Best feasible objective 2994.45 at iteration 17',
    an iterate 6e-6 better that buys it with a 1.2e-5 violation. The bag now stores the result's design."""
    import contextlib
    import io

    from bev_mdo.bag.report import report
    from bev_mdo.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(["optimize", str(ROOT / "examples/golinski.yaml"), "--optimizer", "COBYLA", "--transport", "inprocess",
              "--bag", str(tmp_path / "bag"), "--json", "--quiet"])
    out = json.loads(buf.getvalue())
    report(tmp_path / "bag", tmp_path)
    md = (tmp_path / "report.md").read_text()
    assert f"Best feasible objective {out['objective']:.6g} at iteration {out['result_iteration']} (" in md


def test_the_report_of_a_finished_run_says_it_finished(feasible_run, tmp_path):
    """The first line of a report says how the run ended: here from the end-of-run record the bag holds."""
    from bev_mdo.bag.report import report

    report(feasible_run[1], tmp_path)
    first = (tmp_path / "report.md").read_text().splitlines()[2]
    assert first == "- the run finished: the bag holds its end-of-run record (its result and the answers below)"


def test_an_untampered_unsigned_run_gets_no_warning_in_its_report(tmp_path):
    """report.md carries what the reading left out (a forged record dropped); an in-process run without a key
    is read unverified, as docs/security.md says, and that is no warning (the review saw it bold in every one)."""
    from bev_mdo.bag.report import report
    from bev_mdo.cli import main

    bag = tmp_path / "bag"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["optimize", str(ROOT / "config" / "leaf_nedc.yaml"), "--transport", "inprocess", "--bag", str(bag),
                     "--quiet"]) == 0
    checks: dict = {}
    report(bag, tmp_path / "r", checks=checks)
    assert "not signed" in checks.get("unverified", "")
    lines = (tmp_path / "r" / "report.md").read_text().splitlines()
    assert not [line for line in lines if line.startswith("- **")], lines[:8]


def test_a_report_whose_stored_config_no_longer_loads_says_so(tmp_path):
    # A bag read where the run's user modules are not (moved, or a hand-recorded bag's relative search path):
    # the report left out units, the final analysis and the answers without a word.
    import shutil

    mods = tmp_path / "mods"
    shutil.copytree(ROOT / "examples" / "sellar", mods)
    raw = yaml.safe_load((mods / "sellar_mdf.yaml").read_text())
    raw["search_path"] = [str(mods)]
    (tmp_path / "s.yaml").write_text(yaml.safe_dump(raw))
    rc, bag, _ = _run(tmp_path, tmp_path / "s.yaml", "bag")
    assert rc == 0
    shutil.rmtree(mods)  # the user's modules are gone (a fresh process: this one has imported them)
    import subprocess
    import sys

    p = subprocess.run([sys.executable, "-m", "bev_mdo", "report", str(bag), "--output-dir", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    err = p.stderr
    assert "the config stored in the bag does not load here (" in err, err
    assert "**the config stored in the bag does not load here" in (tmp_path / "out" / "report.md").read_text()


def test_history_table_of_a_multi_start_shows_each_records_start_and_its_seed_in_the_title():
    """With --width 150 a multi-start's table showed `seed` (the same in every record) and left out `start`,
    so its interleaved records could not be told apart."""
    import io

    from bev_mdo.cli.history import choose_columns, print_table

    rows = [{"iteration": i, "objective": 100.0 + i, "max_violation": 0.0, "feasible": True, "status": "ok",
             **{f"design.x{k}": 1.0 + k for k in range(8)}, "mda_evaluations": 3 * i, "start": 1 + i % 3,
             "starts": 3, "seed": 0} for i in range(6)]
    shown, left, _, _ = choose_columns(rows, 100)
    assert "start" in shown and "seed" not in shown + left and "starts" not in shown + left, (shown, left)
    buf = io.StringIO()
    print_table(rows, width=100, file=buf)
    assert "starts 3, seed 0" in buf.getvalue()
