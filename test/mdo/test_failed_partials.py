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
