"""Assembled derivatives (derivatives: analytic) with a discipline differenced alone whose finite-difference
point failed: only the variables whose totals use that partial have no derivative, and the first-order
check names those (it named every variable, whatever the failed partial reached)."""
from __future__ import annotations

import numpy as np
import pytest
from sellar import SELLAR_OPTIMUM, SELLAR_PROBLEM, Failing, SellarDis1, sellar_disciplines

from bev_mdo.mdo import first_order
from bev_mdo.mdo.derivatives import unknown_variables
from bev_mdo.mdo.driver import end_point_check
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.formulations import IDF, MDF
from bev_mdo.mdo.mda import MDA
from bev_mdo.mdo.problem import Problem

TOL = 1e-6  # feasibility tolerance of the check


class Spare:
    """An output nothing optimised reads (no objective, no constraint): ``spare = 3 x``."""

    name = "spare"
    inputs = ("x",)
    outputs = ("spare",)
    units = {"x": "1", "spare": "1"}

    def compute(self, inputs):
        return {"spare": 3.0 * inputs["x"]}


def _form(cls, discs):
    ev = InProcessEvaluator(discs)
    return cls(Problem.from_config(SELLAR_PROBLEM), ev, MDA(ev, tolerance=1e-13), derivatives="analytic")


@pytest.mark.parametrize("cls", [MDF, IDF])
def test_a_failed_partial_in_one_variable_names_only_that_variable(cls):
    # sellar1 has no partials here (Failing hides them) and fails where x > 1; the start is x = 1, so of
    # its finite differences only x + h fails: d y1 / d x is unknown, d y1 / d (z1, z2, y2) are not
    discs = sellar_disciplines()
    discs[0] = Failing(SellarDis1(), "x", 1.0)
    form = _form(cls, discs)
    u = form.to_u(form.x0)
    form.gradients(u)
    assert form.fd_failures == 1
    assert form.unknown_derivatives(u) == ["x"]
    fo = end_point_check(form, form.x0, form.x0, TOL)
    assert fo["unknown_derivatives"] == ["x"]
    assert fo["verdict"] == first_order.NO_PROGRESS and not fo["conditions_hold"]
    assert first_order.verdict_line(fo).startswith("no progress from the start point (no derivative in x: its ")


@pytest.mark.parametrize("cls", [MDF, IDF])
def test_a_failed_partial_no_objective_or_constraint_uses_leaves_the_optimum_verified(cls):
    # at the Sellar optimum (x = 0 on its bound) the spare output's x + h fails: the point's totals do not
    # use d spare / d x, so every derivative is known and the conditions are checked as usual
    form = _form(cls, sellar_disciplines() + [Failing(Spare(), "x", 0.0)])
    design = np.array(list(SELLAR_OPTIMUM.values()))
    if cls is IDF:
        form.start_at(design)  # couplings consistent at the optimum
        x = form.x0
    else:
        x = design
    form.evaluate_batch(x[None])  # the end point of a run was evaluated before its check
    fo = end_point_check(form, x, form.to_x(form.u_bounds[1]), TOL)
    assert form.fd_failures == 1
    assert fo["unknown_derivatives"] == []
    assert fo["verdict"] == first_order.OPTIMUM and fo["conditions_hold"], fo


def test_a_failed_coupling_partial_reaches_every_variable_that_drives_the_loop():
    # MDF: d y1 / d y2 enters the loop solve, and z1, z2 and x all move y2; d y2 / d z1 enters z1's column
    # only; IDF: the partials are the totals, so the failed input is the one variable without a derivative
    specs = {d.name: d for d in sellar_disciplines() + [Spare()]}
    names, quantities = ["z1", "z2", "x"], ["obj", "y1", "y2"]
    assert unknown_variables({("y1", "y2")}, names, quantities, specs) == ["z1", "z2", "x"]
    assert unknown_variables({("y2", "z1")}, names, quantities, specs) == ["z1"]
    assert unknown_variables({("spare", "x")}, names, quantities, specs) == []
    assert unknown_variables({("y1", "y2")}, names + ["y1", "y2"], quantities, {}) == ["y2"]


class Dying:
    """Wraps a discipline that stops working for good after ``calls`` calls (a node that died)."""

    def __init__(self, inner, calls):
        self.inner, self.left = inner, calls
        self.name, self.inputs, self.outputs = inner.name, inner.inputs, inner.outputs
        self.units = getattr(inner, "units", {})
        if hasattr(inner, "compute_partials"):
            self.compute_partials = lambda inputs: self._call(inner.compute_partials, inputs)

    def _call(self, method, inputs):
        self.left -= 1
        if self.left < 0:
            raise RuntimeError("gone")
        return method(inputs)

    def compute(self, inputs):
        return self._call(self.inner.compute, inputs)


@pytest.mark.parametrize("derivatives", ["analytic", "fd"])
def test_a_point_whose_derivatives_fail_when_checked_is_not_verified_not_an_optimum(derivatives):
    """A discipline that died after the result point was evaluated: the check's derivatives (analytic
    partials evaluate the point again; a finite-difference stencil around it) failed, gave zeros, and the
    verdict was 'optimum (first-order conditions hold to 0)' beside 'the result point failed'."""
    discs = sellar_disciplines()
    dying = Dying(discs[1], 10**9)
    ev = InProcessEvaluator([discs[0], dying, discs[2]])
    form = MDF(Problem.from_config(SELLAR_PROBLEM), ev, MDA(ev, tolerance=1e-13), derivatives=derivatives)
    x = np.array([SELLAR_OPTIMUM[k] for k in form.var_names])
    form.evaluate_batch(x[None, :])  # the point, evaluated while the discipline still answered
    assert form.status(x)[0]
    dying.left = 0  # from here on the discipline raises
    fo = end_point_check(form, x, x + 0.1, TOL)
    # the point stands (evaluated before); its derivatives failed (analytic partials evaluate it again, a
    # stencil evaluates points around it): no derivative at all, nothing verified
    assert fo["verdict"] == first_order.STOPPED and fo["unknown_derivatives"] == list(form.var_names)
    assert "cannot be verified" in first_order.verdict_line(fo)


def test_a_result_point_that_failed_is_infeasible_whatever_its_derivatives_say():
    """The check's verdict at a point the disciplines failed at is infeasible, named as such, not a violation of 0."""
    fo = first_order.check(np.zeros(2), -np.ones(2), np.ones(2), np.zeros(2), np.zeros(0), np.zeros((0, 2)),
                           np.zeros(0), np.zeros((0, 2)), names=["a", "b"], ineq_labels=[], eq_labels=[],
                           feasibility_tol=TOL, point_ok=False)
    assert fo["verdict"] == first_order.INFEASIBLE and fo["point_failed"]
    assert first_order.verdict_line(fo) == "infeasible (the point failed: the disciplines gave no value there)"


class Bowl:
    """f = (x - 1)^2 + (y - 2)^2 with analytic partials; ``slip`` adds 0.5 to df/dx (a user's wrong partial)."""

    name, inputs, outputs = "bowl", ("x", "y"), ("f",)
    units = {"x": "1", "y": "1", "f": "1"}

    def __init__(self, slip: bool):
        self.slip = slip

    def compute(self, inputs):
        return {"f": (inputs["x"] - 1.0) ** 2 + (inputs["y"] - 2.0) ** 2}

    def compute_partials(self, inputs):
        return {("f", "x"): 2.0 * (inputs["x"] - 1.0) + 0.5 * self.slip, ("f", "y"): 2.0 * (inputs["y"] - 2.0)}


@pytest.mark.parametrize("wrong", [True, False])
def test_an_optimum_on_a_wrong_analytic_partial_is_not_verified(wrong):
    # An OpenMDAO user's trial: with df/dz 3z for 2z, SLSQP stopped where the wrong gradient is stationary
    # and the check, fed the same gradient, said "optimum", exit 0, 3.4e-4 above the optimum. Here the wrong
    # gradient is 0 at x = 0.75 (the optimum is x = 1): the check there must not say "optimum".
    from bev_mdo.mdo.optimizers import run_optimizer

    ev = InProcessEvaluator([Bowl(wrong)])
    problem = Problem.from_config({"objective": "f", "design_variables": {
        "x": {"lower": -5, "upper": 5, "initial": 3}, "y": {"lower": -5, "upper": 5, "initial": 0}}})
    form = MDF(problem, ev, MDA(ev, tolerance=1e-13), derivatives="analytic")
    x = np.array([0.75, 2.0]) if wrong else run_optimizer("SLSQP", form).x
    form.evaluate_batch(x[None])
    fo = end_point_check(form, x, form.x0, TOL)
    if wrong:
        assert fo["stationarity"] < 1e-12  # by the analytic gradient, the conditions hold
        assert fo["verdict"] == first_order.STOPPED and fo["derivatives_disagree"]["wrt"] == "x", fo
        assert "not with finite differences" in first_order.verdict_line(fo)
    else:
        assert x[0] == pytest.approx(1.0, abs=1e-6)
        assert fo["verdict"] == first_order.OPTIMUM and "derivatives_disagree" not in fo
