"""The first-order check (bev_mdo.mdo.first_order) on small analytic problems with known multipliers."""
from __future__ import annotations

import numpy as np
import pytest

from bev_mdo.mdo.first_order import INFEASIBLE, NO_PROGRESS, OPTIMUM, STOPPED, check

BOX = (np.zeros(2), np.ones(2))
NAMES = ["a", "b"]


def _check(u, grad_f, g=(), jac_g=(), h=(), jac_h=(), lower=BOX[0], upper=BOX[1], **kw):
    m, p = len(g), len(h)
    return check(np.asarray(u, float), lower, upper, np.asarray(grad_f, float), np.asarray(g, float),
                 np.asarray(jac_g, float).reshape(m, 2), np.asarray(h, float), np.asarray(jac_h, float).reshape(p, 2),
                 names=NAMES, ineq_labels=[f"g{i}" for i in range(m)], eq_labels=[f"h{i}" for i in range(p)],
                 feasibility_tol=1e-4, **kw)


def test_interior_minimum_has_no_active_set_and_holds():
    # f = (a - 0.3)^2 + (b - 0.6)^2 at its minimum
    fo = _check([0.3, 0.6], [0.0, 0.0])
    assert fo["verdict"] == OPTIMUM and fo["conditions_hold"]
    assert fo["active_constraints"] == [] and fo["active_bounds"] == [] and fo["equalities"] == []


def test_active_lower_bound_gets_the_gradient_as_its_multiplier():
    # f = (a + 1)^2 + (b - 0.5)^2 on [0, 1]^2: minimum at a = 0 (lower bound), df/da = 2
    fo = _check([0.0, 0.5], [2.0, 0.0])
    assert fo["verdict"] == OPTIMUM
    assert fo["active_bounds"] == [{"name": "a", "kind": "lower", "multiplier": pytest.approx(2.0)}]
    assert fo["stationarity"] == pytest.approx(0.0, abs=1e-12)


def test_active_upper_bound():
    # f = -3 b: pushes b to its upper bound with multiplier 3
    fo = _check([0.2, 1.0], [0.0, -3.0])
    assert fo["verdict"] == OPTIMUM
    assert fo["active_bounds"] == [{"name": "b", "kind": "upper", "multiplier": pytest.approx(3.0)}]


def test_active_inequality_multiplier():
    # min a + 2 b  s.t.  g = 1 - a - b <= 0 on [0, 2]^2  -> (1, 0) with b on its lower bound:
    # grad f = (1, 2) = lam (1, 1) + nu_b (0, 1): lam = 1, nu_b = 1
    fo = _check([1.0, 0.0], [1.0, 2.0], g=[0.0], jac_g=[[-1.0, -1.0]], lower=np.zeros(2), upper=np.full(2, 2.0))
    assert fo["verdict"] == OPTIMUM
    assert fo["active_constraints"] == [{"name": "g0", "value": 0.0, "multiplier": pytest.approx(1.0)}]
    assert fo["active_bounds"] == [{"name": "b", "kind": "lower", "multiplier": pytest.approx(1.0)}]


def test_equality_multiplier_has_its_sign():
    # min a^2 + b^2  s.t.  h = a + b - 1 = 0  -> (0.5, 0.5), grad f = (1, 1), mu = -1
    fo = _check([0.5, 0.5], [1.0, 1.0], h=[0.0], jac_h=[[1.0, 1.0]])
    assert fo["verdict"] == OPTIMUM
    assert fo["equalities"] == [{"name": "h0", "value": 0.0, "multiplier": pytest.approx(-1.0)}]


def test_a_multiplier_of_the_wrong_sign_is_not_an_optimum():
    # min a + b  s.t.  a + b - 1 <= 0 at (0.5, 0.5): the constraint would need lam = -1; the minimum is (0, 0)
    fo = _check([0.5, 0.5], [1.0, 1.0], g=[0.0], jac_g=[[1.0, 1.0]])
    assert fo["verdict"] == STOPPED and not fo["conditions_hold"]
    assert fo["active_constraints"][0]["multiplier"] == pytest.approx(0.0)
    assert fo["stationarity"] == pytest.approx(1.0)


def test_an_inactive_constraint_does_not_help():
    # the same gradient with the constraint far from its limit: interior, not stationary
    fo = _check([0.5, 0.5], [1.0, 1.0], g=[-0.5], jac_g=[[-1.0, -1.0]])
    assert fo["verdict"] == STOPPED and fo["active_constraints"] == []


def test_nearly_active_constraint_with_a_multiplier_fails_complementarity():
    # 0.5 % inside g <= 0 but needed to balance the gradient: not a KKT point
    fo = _check([0.5, 0.5], [1.0, 1.0], g=[-5e-5], jac_g=[[-1.0, -1.0]], tol=1e-5)
    assert fo["active_constraints"][0]["multiplier"] == pytest.approx(1.0)
    assert fo["complementarity"] == pytest.approx(5e-5) and fo["verdict"] == STOPPED


def test_no_move_from_the_start_point_is_said_so():
    fo = _check([0.5, 0.5], [1.0, 0.0], moved=False)
    assert fo["verdict"] == NO_PROGRESS


def test_a_start_point_that_is_the_optimum_is_an_optimum():
    assert _check([0.3, 0.6], [0.0, 0.0], moved=False)["verdict"] == OPTIMUM


def test_violation_above_the_feasibility_tolerance_is_infeasible_even_if_stationary():
    fo = _check([0.5, 0.5], [1.0, 1.0], g=[1e-3], jac_g=[[-1.0, -1.0]])
    assert fo["verdict"] == INFEASIBLE and fo["max_violation"] == pytest.approx(1e-3)
    assert _check([0.3, 0.6], [0.0, 0.0], point_ok=False)["verdict"] == INFEASIBLE


def test_unbounded_variables_are_never_on_a_bound():
    fo = _check([0.0, 0.0], [0.0, 0.0], lower=np.full(2, -np.inf), upper=np.full(2, np.inf))
    assert fo["verdict"] == OPTIMUM and fo["active_bounds"] == []


def test_a_point_outside_its_bounds_is_infeasible_however_stationary():
    # f = (a + 1)^2 + (b - 0.5)^2 stepped to a = -0.2, below its lower bound 0: stationary with the bound
    # "active", but outside it by 0.2 (scaled), more than the feasibility tolerance
    fo = _check([-0.2, 0.5], [1.6, 0.0])
    assert fo["verdict"] == INFEASIBLE and fo["max_violation"] == pytest.approx(0.2)
    assert _check([-1e-6, 0.5], [2.0, 0.0])["verdict"] == OPTIMUM  # within the tolerance: on the bound


def test_a_zero_gradient_from_failed_finite_differences_verifies_nothing():
    # every perturbed point failed: the zeros the optimiser was given are no evidence of stationarity
    from bev_mdo.mdo.first_order import verdict_line

    fo = _check([0.3, 0.6], [0.0, 0.0], moved=False, unknown=["a", "b"])
    assert fo["verdict"] == NO_PROGRESS and not fo["conditions_hold"] and fo["unknown_derivatives"] == ["a", "b"]
    assert verdict_line(fo).startswith("no progress from the start point (no derivative in a, b: their ")
    assert _check([0.3, 0.6], [0.0, 0.0], unknown=["b"])["verdict"] == STOPPED


def test_a_start_point_with_a_zero_gradient_is_an_optimum_that_says_so():
    # a user trial: f = p^2 - q^2 started at its saddle (0, 0) and f = -max(p - 0.5, 0)^2 started in its flat
    # part ended "verdict: optimum" (the conditions hold there) without a word that better points exist
    from bev_mdo.mdo.first_order import verdict_line

    stuck = _check([0.5, 0.5], [0.0, 0.0], moved=False)
    assert stuck["verdict"] == OPTIMUM and "a saddle or a flat region passes this check too" in verdict_line(stuck)
    assert "saddle" not in verdict_line(_check([0.5, 0.5], [0.0, 0.0], moved=True))  # the optimiser got there
    on_bound = _check([0.0, 0.5], [2.0, 0.0], moved=False)  # a start point held by a bound: a real optimum
    assert on_bound["verdict"] == OPTIMUM and "saddle" not in verdict_line(on_bound)


def test_an_end_point_a_rounding_away_from_the_start_has_not_moved(tmp_path, capsys):
    # SLSQP returned p = 0.19999999999999996 for a start at 0.2: the check took it for a move
    import json

    import yaml

    from bev_mdo.cli import main

    (tmp_path / "flat_start.py").write_text(
        "import numpy as np\n\n\nclass Flat:\n    name, inputs, outputs = 'flat', ('p', 'q'), ('ff',)\n"
        "    units = {'p': '1', 'q': '1', 'ff': '1'}\n\n    def compute(self, i):\n"
        "        return {'ff': -np.maximum(i['p'] - 0.5, 0.0) ** 2 + 0 * i['q']}\n")
    raw = {"name": "flat_start", "disciplines": [{"name": "flat", "class": "flat_start:Flat"}],
           "problem": {"objective": "ff", "design_variables": {"p": {"lower": -1, "upper": 1, "initial": 0.2},
                                                               "q": {"lower": -1, "upper": 1, "initial": 0.2}}},
           "optimizer": {"name": "SLSQP"}}
    path = tmp_path / "flat_start.yaml"
    path.write_text(yaml.safe_dump(raw))
    assert main(["optimize", str(path), "--transport", "inprocess", "--no-record", "--json"]) == 0
    fo = json.loads(capsys.readouterr().out)["first_order"]
    assert fo["verdict"] == OPTIMUM and fo["moved"] is False


@pytest.mark.parametrize("optimizer, derivatives, idf", [("chebyshev-pairwise", "analytic", True),
                                                         ("COBYQA", "analytic", False), ("COBYLA", "fd", False)])
def test_a_derivative_free_optimisers_claim_is_not_blamed_on_its_own_gradient(optimizer, derivatives, idf):
    """A user trial: chebyshev-pairwise under IDF (its partials passing check-partials) and COBYQA got 'judged on the
    gradient assembled from the disciplines' analytic partials, the optimiser's own ... a wrong derivative is a common
    cause': a derivative-free optimiser has no gradient of its own, and its stopping rule is the likelier cause."""
    from bev_mdo.mdo.first_order import note_lines

    fo = {"verdict": STOPPED, "derivatives": derivatives, "equalities": [{"name": "q[0] consistency"}] if idf else []}
    (line,) = note_lines(fo, optimizer, converged=True)
    assert line.startswith(f"{optimizer} says it converged") and f"which {optimizer}, derivative-free, does not use" in line
    assert "the optimiser's own" not in line and "as the optimiser's" not in line and "common cause" not in line
    assert "its own stopping rule (optimizer.options)" in line and ("under IDF" in line) == idf
    assert ("check-partials" in line) == (derivatives == "analytic")  # the check's own gradient may be wrong
    (slsqp,) = note_lines(fo, "SLSQP", converged=True)  # a gradient-based one's gradient is the check's
    assert ("the optimiser's own" if derivatives == "analytic" else "as the optimiser's") in slsqp


@pytest.mark.parametrize("jac_g, dependent", [
    ([[0.0, 1.0], [0.0, 1.0]], True),    # a constraint and its copy: the multiplier split between them is arbitrary
    ([[0.0, 1.0], [0.0, -1.0]], False),  # an equality's two rows (<= and >=): one constraint
    ([[0.0, 1.0], [1.0, 0.0]], False),
])
def test_dependent_active_gradients_are_said(jac_g, dependent):
    """An MDO trial: y2[1] <= 3 and its copy g <= 3 printed multipliers 0 and 2 (-0.6667 per unit raised for g),
    while raising g's limit alone changed nothing: the split between dependent constraints is one of many."""
    from bev_mdo.mdo.first_order import note_lines

    fo = check(np.zeros(2), np.full(2, -np.inf), np.full(2, np.inf), np.array([0.0, -2.0]), np.zeros(2),
               np.array(jac_g), np.zeros(0), np.zeros((0, 2)), names=["a", "b"], ineq_labels=["y", "g"], eq_labels=[],
               feasibility_tol=1e-6)
    assert fo.get("dependent_active", False) is dependent
    assert any("linearly dependent" in line for line in note_lines(fo)) is dependent
