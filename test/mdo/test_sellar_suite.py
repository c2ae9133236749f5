"""The canonical Sellar problem through the user-discipline interface only (examples/sellar/):
MDF and IDF in process reach the published optimum; maximisation, the feasibility tolerance,
the best-feasible result and the iteration count on it. (Over ROS: test/ros/test_sellar_ros.py.)"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.optimize import OptimizeResult

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo import optimizers
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.testing import example_config


EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "sellar"
REF_F, REF_Z1 = 3.18339395, 1.977639


def _config(formulation="mdf", **changes):
    return example_config(EXAMPLE / f"sellar_{formulation}.yaml", **changes)


def _run(config, **kw):
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


# (formulation, optimizer, tolerance on f and on z1): what each reaches from the example's start, under
# every OpenBLAS kernel (test_kernels.py re-runs this file under each)
REACHES = [("mdf", "SLSQP", 1e-7), ("idf", "SLSQP", 1e-7), ("mdf", "COBYQA", 1e-6), ("idf", "COBYQA", 1e-6),
           ("mdf", "COBYLA", 1e-6), ("idf", "COBYLA", 1e-6),
           ("mdf", "trust-constr", 1e-6), ("idf", "trust-constr", 1e-6)]


@pytest.mark.parametrize("formulation,optimizer,tol", REACHES)
def test_sellar_reaches_the_published_optimum(formulation, optimizer, tol):
    res = _run(_config(formulation), optimizer=optimizer)
    assert res.feasible and res.formulation == formulation and res.verdict == "optimum"
    assert res.objective == pytest.approx(REF_F, rel=tol)
    assert res.design["z1"] == pytest.approx(REF_Z1, abs=100 * tol)
    assert abs(res.design["z2"]) < 100 * tol and abs(res.design["x"]) < 1e3 * tol
    assert res.outputs["y1"] == pytest.approx(3.16, abs=1e-4)  # the active constraint


def test_the_example_config_resolves_its_module_next_to_it_from_any_working_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    config = load_config(EXAMPLE / "sellar_mdf.yaml")
    assert config["search_path"][:2] == [str(EXAMPLE), str(tmp_path)]
    assert [type(d).__name__ for d in resolve_disciplines(config)] == ["SellarDis1", "SellarDis2", "SellarObjective"]


def test_maximize_reports_the_quantity_and_reaches_the_same_optimum():
    raw = yaml.safe_load((EXAMPLE / "sellar_mdf.yaml").read_text())
    raw["disciplines"].append({"name": "sellar_neg", "class": "sellar:NegatedObjective"})
    raw["problem"]["objective"] = {"name": "neg_obj", "maximize": True}
    raw["search_path"] = [str(EXAMPLE), str(Path(__file__).parent)]
    config = load_config(raw)
    res = _run(config)
    ref = _run(_config("mdf"))
    assert res.maximize and res.objective == pytest.approx(-REF_F, rel=1e-7)
    assert res.outputs["neg_obj"] == pytest.approx(res.objective)
    # every record shows the maximised quantity itself (the negation of the minimised obj)
    assert [r["objective"] for r in res.history] == pytest.approx([-r["objective"] for r in ref.history], rel=1e-9)
    assert res.history[-1]["objective"] > res.history[0]["objective"]  # it went up


def test_the_feasibility_tolerance_is_configurable_and_normalised():
    # y1 >= 3.16 + 3e-5 is violated by 3e-5 / 3.16 ~ 1e-5 (normalised) at the plain optimum:
    # feasible with the default 1e-4, infeasible with 1e-6
    lower = {"y1": {"lower": 3.16 + 3e-5}, "y2": {"upper": 24}}
    x_opt = {"z1": REF_Z1, "z2": 0.0, "x": 0.0}
    loose = _run(_config("mdf", **{"problem.constraints": lower}), x0=x_opt, optimizer="COBYLA")
    assert loose.feasibility_tolerance == 1e-4
    assert loose.history[0]["feasible"] and 1e-6 < loose.history[0]["max_violation"] < 1e-4
    strict = _run(_config("mdf", **{"problem.constraints": lower, "optimizer.feasibility_tolerance": 1e-6}),
                  x0=x_opt, optimizer="COBYLA")
    assert not strict.history[0]["feasible"]
    with pytest.raises(ValueError, match="optimizer.feasibility_tolerance"):
        _config("mdf", **{"optimizer.feasibility_tolerance": -1})


@pytest.fixture
def wandering(monkeypatch):
    """An optimiser that visits x0, the optimum, then ends at a worse feasible point."""
    def run(form, options, callback):
        best = form.to_u(np.array([REF_Z1, 0.0, 0.0]))
        worse = form.to_u(np.array([3.0, 1.0, 1.0]))
        for u in (best, worse):
            form.fun(u)
            callback(form.to_x(u))
        return OptimizeResult(x=worse, success=True, message="done", nit=17)

    monkeypatch.setitem(optimizers.OPTIMIZERS, "wandering", run)


def test_the_result_is_the_best_feasible_point_seen_and_says_so(wandering):
    res = _run(_config("mdf"), optimizer="wandering")
    assert [r["iteration"] for r in res.history] == [0, 1, 2]
    assert res.iterations == 2  # what the records count, not the optimiser's own nit (17)
    assert res.result_iteration == 1 and not res.last_iterate
    assert res.design == pytest.approx(res.history[1]["design"])
    assert res.objective == pytest.approx(REF_F, rel=1e-6)
    assert res.objective < res.history[2]["objective"]
    assert res.outputs["obj"] == pytest.approx(res.objective)
    assert "best feasible point seen" in res.message and "iteration 1" in res.message


def test_iterations_count_the_records():
    res = _run(_config("mdf"))
    assert res.iterations == len(res.history) - 1 == res.history[-1]["iteration"]
    assert res.last_iterate and res.result_iteration == res.iterations


class _FailAbove:
    """Wraps a discipline: NaN outputs where ``x`` exceeds a threshold (a region the model cannot evaluate)."""

    def __init__(self, inner, threshold):
        self.inner, self.threshold = inner, threshold
        self.name, self.inputs, self.outputs = inner.name, inner.inputs, inner.outputs

    def compute(self, inputs):
        out = self.inner.compute(inputs)
        bad = np.asarray(inputs["x"]) > self.threshold
        return {k: np.where(bad, np.nan, v) for k, v in out.items()}


def test_failed_finite_difference_points_are_counted_in_the_result():
    """A perturbed point that fails gives a zero derivative: the result says how many did, so a run that
    stopped early on a degraded gradient is not silent (failures are named where the user looks)."""
    config = _config("mdf")
    clean = _run(config)
    assert clean.fd_failures == 0
    discs = resolve_disciplines(config)
    discs = [_FailAbove(d, 1.0) if d.name == "sellar1" else d for d in discs]  # start x = 1: x + h fails
    res = run_optimization(config, InProcessEvaluator(discs))
    assert res.fd_failures >= 1
    assert res.to_dict()["fd_failures"] == res.fd_failures
