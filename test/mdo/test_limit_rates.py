"""The multipliers in physical units (first_order.limit_rates): how the optimum's objective moves per unit a
limit or bound is raised. A trial loosened Golinski's g_shaft1[1] <= 0 (objective_scale 1000) by 0.01 and saved
2.82, where the printed multiplier, 0.2846 per unit of the scaled objective, read as 0.0028. Each rate is checked
against re-optimising with the limit moved (a first-order prediction: within 10 % of the change)."""
from __future__ import annotations

import pytest

from bev_mdo import Study
from bev_mdo.testing import REPO


def _rates(study: Study) -> tuple[float, dict]:
    r = study.optimize(transport="inprocess")
    assert r.verdict == "optimum"
    rows = r.first_order["active_constraints"] + r.first_order["active_bounds"]
    assert all(type(c["d_objective_d_limit"]) is float for c in rows)  # a library trial: np.float64, unlike the rest
    return r.objective, {c["name"] if "kind" not in c else f"{c['name']} {c['kind']}": c["d_objective_d_limit"]
                         for c in rows}


@pytest.mark.parametrize("config, moved, key, step", [
    ("examples/golinski.yaml", lambda s: s.constrain("g_shaft1[1]", upper=0.01), "g_shaft1[1] <= 0", 0.01),
    ("config/leaf_nedc.yaml", lambda s: s.constrain("accel_time_0_100_s", upper=10.1),
     "accel_time_0_100_s <= 10", 0.1),
    ("config/leaf_nedc.yaml", lambda s: s.bound("battery_kwh", lower=20.1), "battery_kwh lower", 0.1),
    ("examples/ssbj/ssbj_mdf.yaml", lambda s: s.constrain("g_2", upper=0.001), "g_2 <= 0", 0.001),  # maximised
], ids=["objective_scale", "upper_limit", "lower_bound", "maximised"])
def test_a_limits_rate_predicts_the_optimums_move(config, moved, key, step):
    before, rates = _rates(Study(REPO / config))
    after, _ = _rates(moved(Study(REPO / config)))
    predicted = rates[key] * step
    assert after - before == pytest.approx(predicted, rel=0.1), (after - before, predicted)


def test_a_variable_on_its_bound_is_shown_at_the_bound(capsys):
    """Sellar's z2 ended 4.56e-13 above its lower bound 0 and was shown as 'z2 = 4.56397e-13' on that bound."""
    from bev_mdo.cli import main

    assert main(["optimize", str(REPO / "examples" / "sellar" / "sellar_mdf.yaml"), "--transport", "inprocess",
                 "--no-record"]) == 0
    out = capsys.readouterr().out
    assert "  on its lower bound: z2 = 0, multiplier 9.816 (0.9816 per unit raised)" in out, out


def test_no_rate_is_printed_where_the_conditions_do_not_hold(capsys):
    """A review: at 'stopped before convergence' the least-squares multipliers were printed as 'the change of the
    optimum's energy_wh_per_km per unit the limit is raised', of a point that is no optimum."""
    from bev_mdo.cli import main

    assert main(["optimize", str(REPO / "config" / "leaf_nedc.yaml"), "--transport", "inprocess", "--no-record",
                 "--bound", "motor_kw=10:120", "--constraint", "accel_time_0_100_s<=100"]) == 5
    out = capsys.readouterr().out
    assert "what holds the result (multipliers per unit of the scaled variables and normalised constraints):" in out
    assert "raised)" not in out and "change of the optimum" not in out


def test_a_zero_multipliers_rate_has_no_sign():
    """A user trial: a bound with multiplier 0 printed its rate as '(-0 USD per unit raised)' (0 x -1 is -0)."""
    import math

    from bev_mdo.mdo import first_order
    from bev_mdo.mdo.problem import Problem

    problem = Problem.from_config({"objective": "f", "design_variables": {"x": {"lower": 0, "upper": 5, "initial": 1}},
                                   "constraints": {"g": {"upper": 5}}})
    fo = {"active_constraints": [{"name": "g <= 5", "multiplier": 0.0}],
          "active_bounds": [{"name": "x", "kind": "upper", "multiplier": 0.0}]}
    first_order.limit_rates(fo, problem, ["x"], [5.0], ([0.0], [5.0]))
    rates = [r["d_objective_d_limit"] for r in fo["active_constraints"] + fo["active_bounds"]]
    assert rates == [0.0, 0.0] and all(math.copysign(1.0, r) == 1.0 for r in rates), rates
