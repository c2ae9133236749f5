"""What `optimize` prints: rates that mean something per formulation, times that say what they
measure, and the answers; `--bag` works in process."""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from bev_mdo.cli import main

CONFIG = str(Path(__file__).resolve().parents[2] / "config/leaf_nedc.yaml")


def _run(*argv):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["optimize", CONFIG, "--transport", "inprocess", *argv])
    return rc, buf.getvalue()


@pytest.mark.parametrize("formulation,rate", [("mdf", "MDA evals/s"), ("idf", "discipline evals/s")])
def test_progress_rate_fits_the_formulation(formulation, rate):
    rc, out = _run("--formulation", formulation)
    assert rc == 0
    progress = [l for l in out.splitlines() if l.startswith("iter ")]
    assert progress and all(l.endswith(rate) for l in progress)
    assert "optimiser wall time" in out and "(first evaluation to result)" in out
    assert "run time" in out and "wall time " not in out.replace("optimiser wall time", "")
    assert "verdict: optimum (first-order conditions hold to" in out
    assert "on its lower bound: battery_kwh = 20 kWh, multiplier" in out


def test_a_progress_line_says_why_a_design_within_its_constraints_is_infeasible():
    """A 40 kW motor at 2:1 cannot follow the NEDC (the run's design_check): its progress lines said 'max violation
    0  infeasible' and no reason."""
    rc, out = _run("--objective", "vehicle_mass_kg", "--constraint", "range_km>=0", "--constraint",
                   "accel_time_0_100_s<=1000", "--initial", "gear_ratio=2", "--no-record")
    progress = [line for line in out.splitlines() if line.startswith("iter ")]
    assert progress and all(" 0  infeasible: cannot follow the cycle " in line for line in progress), progress


def test_bag_in_process_is_readable_by_history(tmp_path, capsys):
    rc, out = _run("--bag", str(tmp_path / "b"), "--quiet")
    assert rc == 0 and f"bag: {tmp_path / 'b'}" in out
    assert main(["history", str(tmp_path / "b"), "--csv", "-"]) == 0
    csv_text = capsys.readouterr().out
    assert csv_text.startswith("run_id,iteration") and len(csv_text.strip().splitlines()) == 7


def _sellar(tmp_path, optimizer, options, formulation="mdf"):
    import yaml

    sellar = Path(__file__).resolve().parents[2] / "examples" / "sellar"
    raw = yaml.safe_load((sellar / f"sellar_{formulation}.yaml").read_text())
    raw["search_path"] = [str(sellar)]
    raw["optimizer"].update({"name": optimizer, "options": options})
    cfg = tmp_path / "sellar.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    return str(cfg)


def _json(*argv):
    buf, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
        rc = main(["optimize", *argv, "--transport", "inprocess", "--no-record", "--json"])
    return rc, json.loads(buf.getvalue())


def _first_order_numbers(fo):
    assert {"stationarity", "complementarity", "max_violation", "active_constraints", "active_bounds",
            "equalities", "tolerance", "cost"} <= set(fo)
    assert fo["stationarity"] > fo["tolerance"]  # the reason it is not an optimum


def test_a_run_cut_short_is_never_an_optimum_and_exits_5(tmp_path):
    """SLSQP stopped by maxiter: 1 printed a table titled 'Optimum' and exited 0."""
    cfg = _sellar(tmp_path, "SLSQP", {"maxiter": 1})
    rc, res = _json(cfg)
    assert rc == 5 and res["verdict"] == "stopped before convergence" and not res["success"]
    _first_order_numbers(res["first_order"])
    assert res["first_order"]["verdict"] == res["verdict"]
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["optimize", cfg, "--transport", "inprocess", "--no-record", "--quiet"])
    out = buf.getvalue()
    assert rc == 5 and "verdict: stopped before convergence (projected gradient of the Lagrangian" in out
    assert "Optimum" not in out and "verdict: optimum" not in out
    # asked for a fixed budget: the same verdict, exit 0
    rc, res = _json(cfg, "--fixed-budget")
    assert rc == 0 and res["verdict"] == "stopped before convergence"


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
def test_a_cobyqa_run_that_cannot_move_is_no_progress(tmp_path, formulation):
    """COBYQA that never leaves the start point was reported as the optimum, exit 0."""
    rc, res = _json(_sellar(tmp_path, "COBYQA", {"maxfev": 1}, formulation))
    assert rc == 5 and res["verdict"] == "no progress from the start point" and not res["success"]
    assert res["design"] == {"z1": 5.0, "z2": 2.0, "x": 1.0}
    _first_order_numbers(res["first_order"])


def test_a_verified_optimum_carries_its_multipliers(tmp_path):
    rc, res = _json(_sellar(tmp_path, "SLSQP", {}))
    fo = res["first_order"]
    assert rc == 0 and res["verdict"] == "optimum" and res["success"]
    assert fo["stationarity"] <= fo["tolerance"] and fo["complementarity"] <= fo["tolerance"]
    assert [c["name"] for c in fo["active_constraints"]] == ["y1 >= 3.16"]
    assert fo["active_constraints"][0]["multiplier"] > 0
    assert {(b["name"], b["kind"]) for b in fo["active_bounds"]} == {("z2", "lower"), ("x", "lower")}
    # SLSQP's last gradient is reused; its analytic totals are confirmed by central differences (two batches),
    # and steps either side of the free variable look for a kink (one batch)
    assert fo["derivatives_confirmed"] and fo["cost"]["batches"] == 3


def test_an_optimiser_that_did_not_converge_is_said_so_beside_the_table(tmp_path):
    """SLSQP stopped by its iteration limit (or 'Positive directional derivative for linesearch') gave
    success: false in the JSON, but the table, titled 'Optimum', and 'what holds the optimum' said
    nothing: a point short of the optimum read as the optimum (the aerostructure problem, minimised,
    maxiter 3: range 3751.37 against 3733.12)."""
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(["optimize", _sellar(tmp_path, "SLSQP", {"maxiter": 2}), "--transport", "inprocess", "--no-record",
              "--quiet"])
    out = buf.getvalue()
    assert "SLSQP says: Iteration limit reached" in out
    rc, out = _run("--quiet", "--no-record")
    assert rc == 0 and "says:" not in out


def test_starts_reports_how_many_reached_the_best_point(tmp_path):
    rc, res = _json(_sellar(tmp_path, "SLSQP", {}), "--starts", "2", "--seed", "1")
    ms = res["multistart"]
    assert rc == 0 and ms["starts"] == 2 and ms["seed"] == 1 and len(ms["results"]) == 2
    assert 1 <= ms["reached_best"] <= 2 and res["verdict"] == "optimum"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        rc = main(["optimize", CONFIG, "--transport", "inprocess", "--no-record", "--starts", "0"])
    assert rc == 2 and "--starts 0" in err.getvalue() and "Traceback" not in err.getvalue()


def test_multistart_progress_names_each_start_and_the_iterations_say_whose():
    """A multi-start's progress lines did not say which start they were of, and 'iterations 8' (the best start's)
    stood beside MDA evaluations summed over every start, with no word of either."""
    rc, out = _run("--starts", "3")
    assert rc == 0
    progress = [line for line in out.splitlines() if "iter " in line and "MDA evals/s" in line]
    assert progress and all(line.startswith(("start 1/3  iter", "start 2/3  iter", "start 3/3  iter")) for line in progress)
    assert {line[:9] for line in progress} == {"start 1/3", "start 2/3", "start 3/3"}
    # each start's own iterations from 0 (they printed the run's count over the interleaved starts: a user trial)
    for k in "123":
        own = [int(line.split("iter")[1].split()[0]) for line in progress if line.startswith(f"start {k}/3")]
        assert own == list(range(len(own))), (k, own)
    (line,) = [line for line in out.splitlines() if line.startswith("iterations ")]
    best, total = line.split("(start ")[1].split("'s; ")
    assert int(total.split(" over 3 starts)")[0]) == len(progress) - 3  # each start's first record is its start point
    assert line.startswith(f"iterations ") and 1 <= int(best) <= 3


def _strict_json(text: str):
    """JSON as RFC 8259 has it: a bare NaN or Infinity (which Python writes and jq refuses) fails."""
    def refuse(word):
        raise AssertionError(f"{word} in the --json output")
    return json.loads(text, parse_constant=refuse)


def test_json_of_a_run_whose_every_point_failed_is_strict_with_null(tmp_path):
    """The default=float of optimize --json wrote a failed point's outputs as bare NaN."""
    import yaml

    sellar = Path(__file__).resolve().parents[2] / "examples" / "sellar"
    raw = yaml.safe_load((sellar / "sellar_mdf.yaml").read_text())
    raw["search_path"] = [str(sellar), str(Path(__file__).resolve().parents[1] / "data" / "user_modules")]
    raw["disciplines"].append({"name": "raises", "class": "bad_disciplines:Raises"})
    raw["problem"]["constraints"]["w"] = {"upper": 1.0e6}
    raw["optimizer"]["options"] = {"maxiter": 1}
    cfg = tmp_path / "sellar.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    buf, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(err):
        rc = main(["optimize", str(cfg), "--transport", "inprocess", "--no-record", "--json"])
    doc = _strict_json(buf.getvalue())
    assert rc == 1 and not doc["feasible"] and doc["outputs"]["w"] is None, doc["outputs"]


def test_the_start_up_line_says_what_runs_where_with_pools(monkeypatch, tmp_path):
    """With --instances the line said "6 discipline nodes in this process" while the pool ran apart."""
    from bev_mdo import sessions
    from bev_mdo.api.errors import InputError

    class Stop:
        def __init__(self, *args, **kwargs):
            pass

        def __enter__(self):
            raise InputError("stopped by the test before any node starts")

        def __exit__(self, *exc):
            return False

    monkeypatch.setattr(sessions, "OptimizeRosSession", Stop)
    monkeypatch.chdir(tmp_path)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        assert main(["optimize", CONFIG, "--no-record", "--domain-id", "206", "--instances", "energy=2"]) == 2
    assert buf.getvalue().startswith("starting 7 discipline nodes (5 in this process, --compose coordinator; "
                                     "2 in 2 other processes, a process per pool instance: energy x2) (domain 206)")


def test_a_result_projected_onto_its_bounds_is_said_so_beside_the_table(monkeypatch):
    """COBYLA ended Sellar 5e-8 below z2 >= 0; the driver projects it onto the bound, and the terminal says so,
    from the result's `projected` field (the table found it in the message's wording before)."""
    from dataclasses import asdict

    from bev_mdo.mdo.driver import RunResult
    from bev_mdo.testing import end_outside_a_bound

    end_outside_a_bound(monkeypatch, 1, -5e-8)  # z2, lower bound 0
    # the optimiser's message alone, without the driver's words about the projection
    monkeypatch.setattr(RunResult, "to_dict", lambda self: {**asdict(self), "message": self.message.split("; ")[0]})
    sellar = str(Path(CONFIG).parents[1] / "examples/sellar/sellar_mdf.yaml")
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["optimize", sellar, "--transport", "inprocess", "--no-record", "--quiet", "--optimizer", "COBYLA"])
    out = buf.getvalue()
    assert rc == 0 and "verdict: optimum" in out
    line = [ln for ln in out.splitlines() if "projected onto the bounds" in ln]
    assert len(line) == 1 and line[0].startswith("result: iteration ") and "(it was 5e-09 outside them" in line[0]


def test_optimize_of_a_design_that_fails_does_not_explain_it_by_constraints(capsys, sellar_raising):
    # An OpenMDAO user's trial: a point whose analysis failed printed "why the end point is infeasible: no
    # constraint is active and no design variable is on a bound", which explains nothing; the verdict line
    # and "the result point failed: ..." say why.
    from bev_mdo.cli import main

    assert main(["optimize", str(sellar_raising), "--transport", "inprocess", "--no-record"]) == 1
    out = capsys.readouterr().out
    assert "verdict: infeasible (the point failed" in out and "why the end point is infeasible" not in out, out


def test_the_optimisers_own_message_is_printed_whole_restarts_and_all(capsys):
    """'SLSQP says: ... (restart 1 after: Positive directional derivative for linesearch' was cut at the first ';'
    of its own restarts (the JSON message had them all); only what the driver appends after it is left out."""
    from bev_mdo.cli import optimize

    assert main(["optimize", CONFIG, "--transport", "inprocess", "--no-record", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    own = ("Positive directional derivative for linesearch (restart 1 after: Positive directional derivative for "
           "linesearch; restart 2 after: Positive directional derivative for linesearch)")
    doc.update(optimizer_success=False, message=own + "; the result is iteration 3, the best feasible point seen")
    buf = io.StringIO()
    optimize._table({k: v for k, v in doc.items() if k != "baseline"}, doc["baseline"], buf, {})
    said = [line for line in buf.getvalue().splitlines() if line.startswith("SLSQP says: ")]
    assert said == [f"SLSQP says: {own}"]


def test_the_json_names_each_design_variables_and_outputs_unit(capsys):
    """evaluate's and sensitivity's JSON named units; optimize's (and Study.optimize's to_dict()) did not."""
    assert main(["optimize", CONFIG, "--transport", "inprocess", "--no-record", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert set(doc["units"]) == set(doc["design"]) | set(doc["outputs"])
    assert doc["units"]["motor_kw"] == "kW" and doc["units"]["energy_wh_per_km"] == "Wh/km"


def test_the_result_message_says_why_the_last_iterate_was_set_aside():
    """An API trial (a Model 3 RWD-class car on the NEDC, motor speed allowed to 1900 rad/s): SLSQP converged at a
    design within every constraint that cannot follow the cycle; the result's message said 'the last iterate,
    iteration 7, is infeasible' beside its max violation 0, and only the CLI's note said why."""
    import yaml

    from bev_mdo import Study

    raw = yaml.safe_load(Path(CONFIG).read_text())
    raw["vehicle"].update(drag_area_m2=0.511, rolling_resistance=0.0075, air_density_kg_m3=1.2, wheel_radius_m=0.334,
                          regen_fraction=0.6, glider_kg=1149.0, load_kg=75.0)
    raw["problem"]["design_variables"] = {"motor_kw": {"lower": 100, "upper": 250, "initial": 208},
                                          "gear_ratio": {"lower": 6, "upper": 12, "initial": 9.04},
                                          "battery_kwh": {"lower": 40, "upper": 80, "initial": 57.5}}
    raw["problem"]["constraints"] = {"range_km": {"lower": 400}, "motor_speed_max_rad_s": {"upper": 1900},
                                     "accel_time_0_100_s": {"upper": 7}}
    raw["problem"].pop("baseline", None)
    d = Study(raw).optimize(transport="inprocess").to_dict()
    assert d["ended"]["cannot_follow"] and d["ended"]["max_violation"] == 0 and not d["last_iterate"], d["ended"]
    assert d["message"].endswith(f"(the last iterate, iteration {d['ended']['iteration']}, is infeasible: it cannot "
                                 "follow the drive cycle)"), d["message"]
