"""An end point at a kink of the model: the first-order conditions cannot hold there, and the verdict said
only "stopped before convergence" (a van's efficiency map: every optimiser ended at gear_ratio 9.49333 with
the projected gradient 0.00287, exit 5). The check now names the variable and its one-sided slopes; a smooth
objective, curved or noisy, is not called kinked."""
from __future__ import annotations

import numpy as np
import pytest

from bev_mdo.mdo import first_order
from bev_mdo.mdo.driver import end_point_check, kinks
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.formulations import MDF
from bev_mdo.mdo.mda import MDA
from bev_mdo.mdo.problem import Problem


class Cost:
    """f = |x - 0.3| x jump + 5 (x - 0.3) + (y - 0.5)^2 x curvature + noise x (a number drawn per point, the
    same at every call: an MDA converged to a tolerance): a kink in x where jump is not 0."""

    name = "cost"
    inputs = ("x", "y")
    outputs = ("f",)

    def __init__(self, jump=1.0, curvature=1.0, noise=0.0):
        self.jump, self.curvature, self.noise = jump, curvature, noise

    def compute(self, inputs):
        x, y = inputs["x"], inputs["y"]
        drawn = [np.random.default_rng(abs(hash((float(a), float(b))))).uniform(-1, 1) for a, b in zip(x, y)]
        return {"f": self.jump * np.abs(x - 0.3) + 5 * (x - 0.3) + self.curvature * (y - 0.5) ** 2
                + self.noise * np.array(drawn)}


def _form(disc):
    ev = InProcessEvaluator([disc])
    problem = Problem.from_config({"objective": "f", "design_variables": {
        "x": {"lower": 0.0, "upper": 1.0, "initial": 0.5}, "y": {"lower": 0.0, "upper": 1.0, "initial": 0.2}}})
    return MDF(problem, ev, MDA(ev))


def test_an_end_point_at_a_kink_names_it_with_its_one_sided_slopes():
    form = _form(Cost(jump=1.0))
    x = np.array([0.3, 0.5])
    fo = end_point_check(form, x, np.array([0.5, 0.2]), 1e-6)
    assert fo["verdict"] == first_order.STOPPED  # the forward difference sees the right slope, 6, not 0
    assert [k["name"] for k in fo["kinks"]] == ["x"]
    assert fo["kinks"][0]["left"] == pytest.approx(4.0, rel=1e-4) and fo["kinks"][0]["right"] == pytest.approx(6.0, rel=1e-4)
    assert "kink at the point in x (one-sided slopes 4 and 6)" in first_order.verdict_line(fo)


@pytest.mark.parametrize("disc", [Cost(jump=0.0, curvature=1e3), Cost(jump=0.0, noise=1e-8)])
def test_a_smooth_objective_curved_or_noisy_has_no_kink(disc):
    form = _form(disc)
    u = form.to_u(np.array([0.3, 0.2]))
    f0 = form.evaluate_batch(form.to_x(u)[None, :])[0][0]
    assert kinks(form, u, f0, 5.0) == []
