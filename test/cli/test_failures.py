"""Failures named where the user looks, in-process (no ROS): a user discipline that
raises is named on the console with its first error and the progress line shows no penalty as
an objective; a discipline that never returns fails after the ROS timeout budget instead of
hanging `--transport inprocess` forever."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from bev_mdo.testing import REPO

HERE = Path(__file__).resolve().parent


def _run(tmp_path, name: str, cls: str, ros: dict, optimizer: str = "SLSQP",
         command: tuple = ("optimize",)) -> subprocess.CompletedProcess:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed",
                          {"name": name, "class": f"bad_disciplines:{cls}"}]
    raw["problem"]["constraints"][f"{name}_kw"] = {"upper": 1.0e9}
    raw["optimizer"] = {"name": optimizer, "options": {"maxiter": 2} if optimizer == "SLSQP" else {}}
    raw["ros"] = ros
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    env = {**os.environ, "PYTHONPATH": f"{HERE}{os.pathsep}{REPO}"}
    return subprocess.run([sys.executable, "-m", "bev_mdo", command[0], str(path), *command[1:], "--transport",
                           "inprocess", "--json"], capture_output=True, text=True, env=env, timeout=120, cwd=tmp_path)


def test_a_failing_discipline_is_named_and_no_penalty_is_shown_as_objective(tmp_path):
    p = _run(tmp_path, "broken", "Broken", {})
    assert p.returncode == 1, p.stderr[-2000:]  # infeasible: every point failed
    named = [l for l in p.stderr.splitlines() if l.startswith("discipline 'broken' failed:")]
    assert len(named) == 1 and "the broken model refuses every motor" in named[0], p.stderr[-2000:]
    progress = [l for l in p.stderr.splitlines() if l.startswith("iter")]
    assert progress and all("not evaluated" in l and "10000000000" not in l for l in progress), progress
    out = json.loads(p.stdout)
    assert "refuses every motor" in out["discipline_errors"]["broken"]


def test_a_discipline_that_never_returns_fails_after_the_ros_timeout_budget(tmp_path):
    # the budget applies to every discipline: 6 s, not a fraction of one, so that the built-in ones, slow on a
    # loaded host (a whole-suite run once saw energy pass 0.4 s), are never taken for hung ones
    p = _run(tmp_path, "hang", "Hang", {"timeout_s": 3.0, "retries": 1})
    assert p.returncode == 4, p.stderr[-2000:]  # a discipline stopped answering (every point failed: infeasible too)
    assert "discipline 'hang' failed:" in p.stderr and "no answer within 6 s" in p.stderr, p.stderr[-2000:]
    out = json.loads(p.stdout)
    assert "treated as hung" in out["discipline_errors"]["hang"]


def test_a_discipline_that_stops_answering_mid_run_is_not_an_optimum(tmp_path):
    """The start point was evaluated, then the discipline hung: every later point failed, the best
    point seen is the start. That is reported, with a warning naming the discipline and exit 4,
    never as an optimum with exit 0."""
    p = _run(tmp_path, "late", "HangLater", {"timeout_s": 3.0, "retries": 1})  # 6 s: see above
    assert p.returncode == 4, p.stderr[-2000:]
    out = json.loads(p.stdout)
    assert out["feasible"] and out["unresponsive_disciplines"] == ["late"], out
    warned = [l for l in p.stderr.splitlines() if l.startswith("warning: late stopped answering")]
    assert len(warned) == 1 and "not an optimum" in warned[0], p.stderr[-2000:]


@pytest.mark.parametrize("optimizer", ["SLSQP", "COBYLA"])
def test_a_start_point_whose_neighbourhood_failed_is_not_an_optimum(tmp_path, optimizer):
    """Every point but the start failed: the finite differences there gave the optimiser zero
    derivatives, which are no evidence of stationarity. The verdict says the conditions could not be
    verified (it said 'optimum (first-order conditions hold to 0)'), and the exit status is 5."""
    p = _run(tmp_path, "only", "OnlyAtStart", {}, optimizer)
    out = json.loads(p.stdout)
    assert out["design"] == {"motor_kw": 80.0, "gear_ratio": 8.0, "battery_kwh": 24.0}, out["design"]
    assert out["verdict"] == "no progress from the start point", out["first_order"]
    assert out["first_order"]["unknown_derivatives"] == ["motor_kw", "gear_ratio", "battery_kwh"]
    assert p.returncode == 5, p.stderr[-2000:]


def test_one_number_for_a_whole_batch_is_an_error_naming_the_discipline(tmp_path):
    """A discipline that returns one scalar for a batch (here its sum) is not broadcast to every point."""
    p = _run(tmp_path, "summed", "Summed", {})
    assert p.returncode == 2 and not p.stdout.strip(), p.stderr[-2000:]
    lines = p.stderr.strip().splitlines()
    assert len(lines) == 1 and "discipline 'summed': output 'summed_kw' has shape ()" in lines[0], lines
    assert "Traceback" not in p.stderr


def test_a_discipline_slow_to_prepare_is_not_taken_for_a_hung_one(tmp_path):
    """A discipline's prepare() (its one-time work, such as the quasi-static model's compile after an install)
    runs before its first call, outside the timeout budget: 8 s against a budget of 6 s is not a hang."""
    p = _run(tmp_path, "slow_start", "SlowStart", {"timeout_s": 3.0, "retries": 1})
    assert p.returncode in (0, 5), p.stderr[-2000:]  # an optimum, or feasible at maxiter 2: never 1 or 4 (hung)
    out = json.loads(p.stdout)
    assert out["feasible"] and not out.get("discipline_errors") and not out.get("unresponsive_disciplines"), out
    assert "failed" not in p.stderr, p.stderr[-2000:]


def test_in_process_optimize_prepares_the_disciplines_before_the_optimiser_starts(tmp_path, monkeypatch):
    """The quasi-static model compiled inside the first timed evaluation in process (over ROS before it), so
    the optimiser wall time and its evaluations/s (2 against 94 over ROS on a Kona problem) counted numba."""
    import bev_mdo.mdo.driver as driver
    from bev_mdo import Study

    (tmp_path / "prepare_probe.py").write_text(
        "class Probe:\n    name = 'probe'\n    inputs = ('motor_kw',)\n    outputs = ('probe_kw',)\n"
        "    units = {'motor_kw': 'kW', 'probe_kw': 'kW'}\n    ready = False\n\n"
        "    def prepare(self):\n        self.ready = True\n\n"
        "    def compute(self, inputs):\n        return {'probe_kw': inputs['motor_kw']}\n")
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed",
                          {"name": "probe", "class": "prepare_probe:Probe"}]
    raw["search_path"] = [str(tmp_path)]
    import bev_mdo.mdo.multistart  # noqa: F401  bound to the real run_optimization before the spy replaces it
    # (imported first under the spy, multistart kept it for good, and a later multistart run called it)
    seen, run = [], driver.run_optimization

    def spy(settings, evaluator, **kw):
        seen.append(evaluator.disciplines["probe"].ready)
        return run(settings, evaluator, **kw)

    monkeypatch.setattr(driver, "run_optimization", spy)
    Study(raw).optimize(transport="inprocess")
    assert seen == [True]


def test_a_global_sensitivity_whose_model_fails_says_where_not_a_stencil(tmp_path):
    """It said 'the model failed on the FD stencil' (a Sobol' sample has none) and exit 2, the status of
    a user's mistake; then exit 7 with 'RuntimeError: ... (raised at sensitivity.py:142)', read as a crash, and
    no design named. A model that fails at sampled points is exit 1, as a result point that failed."""
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed",
                          {"name": "broken", "class": "bad_disciplines:Broken"}]
    raw["problem"]["constraints"]["broken_kw"] = {"upper": 1.0e9}
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    env = {**os.environ, "PYTHONPATH": f"{HERE}{os.pathsep}{REPO}"}
    p = subprocess.run([sys.executable, "-m", "bev_mdo", "sensitivity", str(path), "--global", "morris", "--samples", "4",
                        "--transport", "inprocess"], capture_output=True, text=True, env=env, timeout=120, cwd=tmp_path)
    err = p.stderr.strip().splitlines()
    assert p.returncode == 1 and len(err) == 1, p.stderr[-2000:]
    assert "error: the model failed at 16 of the 16 sampled points (the indices need a value at every one: narrow " \
           "the bounds to where it answers); first at motor_kw=" in err[0] and "stencil" not in err[0], err[0]
    assert ": broken:" in err[0] and "RuntimeError" not in err[0] and "raised at" not in err[0]


@pytest.mark.parametrize("command", [("evaluate",), ("sensitivity", "--order", "1")])
def test_every_command_prepares_bounds_and_quiets_the_disciplines(tmp_path, command):
    """Only optimize prepared a discipline and bounded its calls: evaluate, sweep, sensitivity, check-totals
    (and check-partials, compare, report) never ran prepare() (every point failed: no attribute 'k'; one that
    raised was ignored), a hung compute hung evaluate for ever, and a print in compute came before --json's JSON."""
    p = _run(tmp_path, "needs_prepare", "NeedsPrepare", {}, command=command)
    assert p.returncode == 0, p.stderr[-2000:]
    json.loads(p.stdout)
    p = _run(tmp_path, "prepare_fails", "PrepareFails", {}, command=command)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1, p.stderr[-2000:]
    assert "discipline 'prepare_fails': prepare() failed: FileNotFoundError: table.csv is missing" in lines[0]
    p = _run(tmp_path, "talks", "Talks", {}, command=command)
    assert p.returncode == 0 and "computing talks_kw" in p.stderr, p.stderr[-2000:]
    json.loads(p.stdout)  # the JSON alone on stdout


def test_a_discipline_that_never_returns_fails_evaluate_after_the_budget(tmp_path):
    p = _run(tmp_path, "hang", "Hang", {"timeout_s": 3.0, "retries": 1}, command=("evaluate",))
    assert p.returncode == 1, p.stderr[-2000:]
    out = json.loads(p.stdout)
    assert not out["ok"] and "no answer within 6 s" in out["error"], out



@pytest.fixture(scope="module")
def stopped_run(tmp_path_factory) -> tuple[subprocess.CompletedProcess, Path]:
    """Differential evolution with a discipline that hangs in its third generation, its bag in ``b``."""
    tmp = tmp_path_factory.mktemp("stopped")
    return _run(tmp, "gen", "HangInGeneration", {"timeout_s": 3.0, "retries": 1}, "differential_evolution",
                command=("optimize", "--bag", "b")), tmp / "b"


def test_a_discipline_that_stops_answering_stops_the_optimiser(stopped_run):
    """DE ran on to maxiter 200 with every point failing, and the JSON said "Maximum number of iterations has been
    exceeded", result_iteration 200 and last_iterate true for a point found in generation 1. The run stops the
    optimiser once the discipline is declared unresponsive, and says so; the result is the iteration where its
    point was found."""
    p, _ = stopped_run
    assert p.returncode == 4, p.stderr[-2000:]
    out = json.loads(p.stdout)
    assert out["unresponsive_disciplines"] == ["gen"] and out["iterations"] < 10, out["iterations"]
    assert out["message"].startswith(f"stopped after iteration {out['iterations']}: discipline 'gen' stopped "
                                     "answering"), out["message"]
    assert out["stopped"] and not out["optimizer_success"] and out["feasible"], out
    record = out["result_iteration"]  # DE's best point, recorded once per generation from where it was found
    assert not out["last_iterate"] and record < out["iterations"], (record, out["iterations"])
    assert f"the result is iteration {record}, the best feasible point seen" in out["message"]


def test_the_report_of_a_run_a_discipline_stopped_says_so_first(stopped_run, tmp_path):
    """`bev-mdo report` of a run that ended with exit 4 read like a finished run ("Final iterate", "What holds
    the design"): its first line now says which discipline stopped answering."""
    from bev_mdo.bag.report import report

    p, bag = stopped_run
    assert p.returncode == 4, p.stderr[-2000:]
    report(bag, tmp_path)
    md = (tmp_path / "report.md").read_text()
    first = md.splitlines()[2]
    assert first.startswith("- **the run ended early (exit status 4)**: stopped after iteration ") and \
        "discipline 'gen' stopped answering" in first, first
    result = json.loads(p.stdout)["result_iteration"]  # where the result was found, as the JSON says
    assert f"## The run's result (iteration {result})" in md and "## Final iterate" not in md, md[:1500]


LOOP = '''
import numpy as np

A = np.array([[1.0, 0.5], [0.5, 1.0]])  # its eigenvalues 1.5 and 0.5: Gauss-Seidel diverges but at its fixed point


class D1:
    name, inputs, outputs, shapes = "d1", ("x", "y2"), ("y1",), {"x": 2, "y2": 2, "y1": 2}
    units = dict.fromkeys(("x", "y2", "y1"), "1")

    def compute(self, inputs):
        return {"y1": inputs["x"] - inputs["y2"] @ A.T}


class D2:
    name, inputs, outputs, shapes = "d2", ("y1", "z"), ("y2",), {"y1": 2, "y2": 2}
    units = dict.fromkeys(("y1", "z", "y2"), "1")

    def compute(self, inputs):
        return {"y2": inputs["y1"] + inputs["z"][:, None]}


class D3:
    name, inputs, outputs, shapes = "d3", ("y1", "y2"), ("f",), {"y1": 2, "y2": 2}
    units = dict.fromkeys(("y1", "y2", "f"), "1")

    def compute(self, inputs):
        return {"f": np.sum((inputs["y1"] - [1.0, 2.0]) ** 2, axis=1) + np.sum((inputs["y2"] - 3.0) ** 2, axis=1)}
'''


def test_an_mda_that_diverges_during_the_run_is_said_with_its_cause(tmp_path):
    """An MDO trial: a two-discipline loop that Gauss-Seidel converges only at the start point (its fixed point)
    ended 'no progress from the start point', exit 5, and 'did not converge' was said nowhere: not in the output,
    the notes nor the JSON. The run now says how many points gave no value and the first one's cause."""
    p = _loop_run(tmp_path, "mdf", "optimize", "loop2.yaml", "--transport", "inprocess")
    said = [line for line in p.stdout.splitlines() if "point(s) of the run gave no value" in line]
    assert len(said) == 1 and "the first: MDA loop ['d1', 'd2'] did not converge" in said[0], p.stdout[-2000:]
    assert "mda.method: newton may converge" in said[0]


def test_idf_check_totals_at_a_design_whose_mda_fails_says_where_the_couplings_are(tmp_path):
    """An MDO trial: check-totals --at under IDF put the couplings where one MDA of the design puts them, and
    where that MDA diverged it checked them at the run's start values with no word (exit 0)."""
    p = _loop_run(tmp_path, "idf", "check-totals", "loop2.yaml", "--at", "x[0]=5.5,x[1]=6,z=1.3333333333",
                  "--transport", "inprocess")
    assert p.stderr.count("note: the MDA of this design failed (MDA loop ['d1', 'd2'] did not converge") == 1, p.stderr
    assert "the couplings keep the values a run starts from (shown in the header)" in p.stderr


def _loop_run(tmp_path, formulation: str, *argv) -> subprocess.CompletedProcess:
    """``bev-mdo argv`` on the LOOP problem (its constrained optimum x = (5.5, 6), z = 4/3, f = 1/3)."""
    (tmp_path / "loop2.py").write_text(LOOP)
    cfg = {"name": "loop2", "disciplines": [{"name": f"d{k}", "class": f"loop2:D{k}"} for k in (1, 2, 3)],
           "problem": {"objective": "f", "design_variables": {
               "x": {"shape": 2, "lower": -10, "upper": 10, "initial": [0, 0]},
               "z": {"lower": -5, "upper": 5, "initial": 0}},
               "constraints": {"y2[1]": {"upper": 3}}, "coupling_guesses": {"y2": 0.0}},
           "formulation": formulation, "mda": {"method": "gauss_seidel", "tolerance": 1e-12, "max_iterations": 100},
           "optimizer": {"name": "SLSQP"}}
    (tmp_path / "loop2.yaml").write_text(yaml.safe_dump(cfg))
    return subprocess.run([sys.executable, "-m", "bev_mdo", *argv], capture_output=True, text=True, env=os.environ,
                          timeout=120, cwd=tmp_path)
