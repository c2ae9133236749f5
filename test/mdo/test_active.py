"""The end-of-run answers (bev_mdo.mdo.active): active limits, bounds, violations, blocking bounds."""
from __future__ import annotations

import pytest

from bev_mdo.disciplines.common import UNITS
from bev_mdo.mdo import active
from bev_mdo.mdo.active import summary_lines
from bev_mdo.mdo.problem import Problem

def analyse(*args, **kwargs):
    """active.analyse with the built-in disciplines' declared units."""
    return active.analyse(*args, units=UNITS, **kwargs)


PROBLEM = Problem.from_config({
    "objective": "energy_wh_per_km",
    "design_variables": {"motor_kw": {"lower": 40, "upper": 120, "initial": 80},
                         "battery_kwh": {"lower": 20, "upper": 30, "initial": 24}},
    "constraints": {"range_km": {"lower": 250}, "accel_time_0_100_s": {"upper": 10}},
})


def test_feasible_end_names_active_limits_and_bounds_with_units():
    a = analyse(PROBLEM, {"motor_kw": 75.0, "battery_kwh": 20.0},
                {"range_km": 300.0, "accel_time_0_100_s": 10.0 - 1e-9})
    assert a["feasible"] and a["violated"] == []
    assert [(e["name"], e["kind"], e["unit"]) for e in a["active_constraints"]] == [("accel_time_0_100_s", "upper", "s")]
    assert [(b["name"], b["kind"], b["unit"]) for b in a["bounds"]] == [("battery_kwh", "lower", "kWh")]
    assert "active: accel_time_0_100_s <= 10 s, margin 0 s" in a["lines"]
    assert "on its lower bound: battery_kwh = 20 kWh (bound 20 kWh, margin 0 kWh)" in a["lines"]


def test_no_active_limit_says_so_without_calling_it_an_optimum():
    a = analyse(PROBLEM, {"motor_kw": 75.0, "battery_kwh": 25.0}, {"range_km": 300.0, "accel_time_0_100_s": 9.0})
    assert a["lines"] == ["no constraint is active and no design variable is on a bound"]


def test_a_margin_of_a_tenth_of_a_per_mille_is_active_but_one_per_cent_is_not():
    a = analyse(PROBLEM, {"motor_kw": 75.0, "battery_kwh": 25.0}, {"range_km": 250.2, "accel_time_0_100_s": 9.9})
    assert [e["name"] for e in a["active_constraints"]] == ["range_km"]


def test_a_violation_within_the_runs_feasibility_tolerance_is_not_called_violated():
    """The answers judge a limit with the run's tolerance (optimizer.feasibility_tolerance, default 1e-4
    of the bound's scale), as the run's own "feasible" does: 5e-6 relative is within it, 1e-3 is not."""
    design = {"motor_kw": 75.0, "battery_kwh": 25.0}
    near = analyse(PROBLEM, design, {"range_km": 250.0 * (1 - 5e-6), "accel_time_0_100_s": 9.0})
    assert near["feasible"] and near["violated"] == []
    assert [e["name"] for e in near["active_constraints"]] == ["range_km"]
    strict = analyse(PROBLEM, design, {"range_km": 250.0 * (1 - 5e-6), "accel_time_0_100_s": 9.0}, feas_tol=1e-6)
    assert [e["name"] for e in strict["violated"]] == ["range_km"]
    far = analyse(PROBLEM, design, {"range_km": 250.0 * (1 - 1e-3), "accel_time_0_100_s": 9.0})
    assert [e["name"] for e in far["violated"]] == ["range_km"]


def test_infeasible_end_names_violation_and_the_bound_that_blocks():
    # range short by 2 km; battery on its upper bound; more battery would give more range
    jac = {"range_km": {"motor_kw": -0.05, "battery_kwh": 8.0},
           "accel_time_0_100_s": {"motor_kw": -0.15, "battery_kwh": 0.05}}
    a = analyse(PROBLEM, {"motor_kw": 80.0, "battery_kwh": 30.0}, {"range_km": 248.0, "accel_time_0_100_s": 10.0},
                jacobian=jac)
    assert not a["feasible"]
    (v,) = a["violated"]
    assert v["name"] == "range_km" and v["violation"] == pytest.approx(2.0)
    assert [(b["variable"], b["bound"]) for b in v["blocked_by"]] == [("battery_kwh", "upper")]
    assert v["blocked_by"][0]["rate"] == pytest.approx(8.0)
    # reducing the range violation over the free variable (less motor) slows the 0-100 time
    assert v["conflicts_with"] == ["accel_time_0_100_s <= 10"]
    text = "\n".join(a["lines"])
    assert "violated: range_km >= 250 km is 248 km, short by 2 km" in text
    assert "blocked by battery_kwh on its upper bound (8 km per kWh)" in text
    # without units (Sellar's obj over z2): "(1.73 1 per unit)"
    units = {"range_km": "", "battery_kwh": ""}
    bare = active.analyse(PROBLEM, {"motor_kw": 80.0, "battery_kwh": 30.0}, {"range_km": 248.0, "accel_time_0_100_s": 10.0},
                          jacobian=jac, units=units)
    assert "blocked by battery_kwh on its upper bound (8 per unit)" in "\n".join(bare["lines"])


def test_an_active_limit_conflicts_only_when_no_step_spares_it():
    """The range is short and the top speed active: the steepest way to more range (more battery, less motor)
    cuts the top speed, which was called a conflict ('reducing it would break top_speed_kmh >= 146'), though
    more battery alone gives range and leaves the top speed as it is (a user trial on a Bolt config). Only
    when every step that gives range costs top speed is the top speed named."""
    problem = Problem.from_config({"objective": "energy_wh_per_km", "design_variables": {
        "motor_kw": {"lower": 50, "upper": 200}, "battery_kwh": {"lower": 30, "upper": 90}},
        "constraints": {"range_km": {"lower": 595}, "top_speed_kmh": {"lower": 146}}})
    point = ({"motor_kw": 148.0, "battery_kwh": 63.0}, {"range_km": 593.9, "top_speed_kmh": 146.0})
    free = {"range_km": {"motor_kw": -0.5, "battery_kwh": 8.0}, "top_speed_kmh": {"motor_kw": 0.3, "battery_kwh": 0.0}}
    (v,) = analyse(problem, *point, jacobian=free)["violated"]
    assert v["conflicts_with"] == [] and v["free_way"]
    assert "the optimiser stopped short" in "\n".join(analyse(problem, *point, jacobian=free)["lines"])
    # heavier with more battery, and the motor already on its upper bound: every step to range costs top speed
    held = {"range_km": {"motor_kw": -0.5, "battery_kwh": 8.0}, "top_speed_kmh": {"motor_kw": 0.3, "battery_kwh": -0.2}}
    (v,) = analyse(problem, {"motor_kw": 200.0, "battery_kwh": 63.0}, point[1], jacobian=held)["violated"]
    assert v["conflicts_with"] == ["top_speed_kmh >= 146"] and not v["free_way"]
    # two violations that trade: more range costs acceleration, faster acceleration costs range
    both = Problem.from_config({"objective": "energy_wh_per_km", "design_variables": {
        "motor_kw": {"lower": 50, "upper": 200}, "battery_kwh": {"lower": 30, "upper": 90}},
        "constraints": {"range_km": {"lower": 595}, "accel_time_0_100_s": {"upper": 4}}})
    jac = {"range_km": {"motor_kw": -0.5, "battery_kwh": 8.0}, "accel_time_0_100_s": {"motor_kw": -0.01, "battery_kwh": 0.02}}
    a = analyse(both, {"motor_kw": 200.0, "battery_kwh": 63.0}, {"range_km": 593.9, "accel_time_0_100_s": 5.26},
                jacobian=jac)
    rng, acc = a["violated"]
    assert rng["trades_with"] == ["accel_time_0_100_s <= 4"] and acc["trades_with"] == ["range_km >= 595"]
    assert not rng["free_way"] and not acc["free_way"] and rng["conflicts_with"] == acc["conflicts_with"] == []
    assert "reducing it would worsen accel_time_0_100_s <= 4 (violated too)" in "\n".join(a["lines"])


def test_a_bound_on_the_wrong_side_does_not_block():
    jac = {"range_km": {"motor_kw": 0.0, "battery_kwh": 8.0}, "accel_time_0_100_s": {}}
    a = analyse(PROBLEM, {"motor_kw": 80.0, "battery_kwh": 20.0}, {"range_km": 248.0, "accel_time_0_100_s": 9.0},
                jacobian=jac)
    assert a["violated"][0]["blocked_by"] == []
    assert "no design-variable bound blocks it" in "\n".join(a["lines"])


def test_without_a_jacobian_the_violation_is_still_named():
    a = analyse(PROBLEM, {"motor_kw": 80.0, "battery_kwh": 30.0}, {"range_km": 248.0, "accel_time_0_100_s": 9.0})
    assert "blocked_by" not in a["violated"][0]
    assert summary_lines(a)[0].startswith("violated: range_km >= 250 km")


def test_answers_for_builds_the_disciplines_only_for_a_jacobian():
    """The engine does not read the application config: the caller gives the disciplines, or a
    function building them, called only when a violated end needs the Jacobian."""
    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.mdo.active import answers_for
    from bev_mdo.testing import REPO

    cfg = load_config(REPO / "config" / "leaf_nedc.yaml")
    built = []

    def build():
        built.append(1)
        return resolve_disciplines(cfg)

    design = {"motor_kw": 80.0, "gear_ratio": 8.0, "battery_kwh": 24.0}
    fine = {"range_km": 200.0, "accel_time_0_100_s": 9.0, "motor_speed_max_rad_s": 100.0}
    assert answers_for(cfg, design, fine, build)["violated"] == [] and built == []
    short = answers_for(cfg, design, {**fine, "range_km": 10.0}, build)
    assert built == [1] and "jacobian_error" not in short
    assert [v["name"] for v in short["violated"]] == ["range_km"]


def test_a_failed_point_has_no_value_rather_than_an_infinite_shortfall():
    """bev-mdo optimize from a start where acceleration cannot reach 100 km/h (gear ratio 1, 40 kW) said
    'violated: range_km >= 170 km is nan km, short by inf km / no design-variable bound blocks it' for
    every constraint, though only the point had failed."""
    nan = float("nan")
    jac = {"range_km": {"motor_kw": nan, "battery_kwh": nan}, "accel_time_0_100_s": {"motor_kw": nan}}
    a = analyse(PROBLEM, {"motor_kw": 40.0, "battery_kwh": 20.0}, {"range_km": nan, "accel_time_0_100_s": nan},
                jacobian=jac)
    assert not a["feasible"] and [e["name"] for e in a["violated"]] == ["range_km", "accel_time_0_100_s"]
    text = "\n".join(a["lines"])
    assert "no value: range_km >= 250 km (the point failed)" in text
    assert "no value: accel_time_0_100_s <= 10 s (the point failed)" in text
    assert "nan" not in text and "inf" not in text and "blocks it" not in text
    assert "on its lower bound: motor_kw = 40 kW" in text


EQUALITY = Problem.from_config({
    "objective": "energy_wh_per_km",
    "design_variables": {"motor_kw": {"lower": 40, "upper": 120, "initial": 80}},
    "constraints": {"range_km": {"lower": 250, "upper": 250}},
})


def test_an_equality_is_one_limit_name_equals_value_not_two_inequalities():
    """aerostructure's lift: {lower: 0.5, upper: 0.5} was listed as 'lift >= 0.5' and 'lift <= 0.5'."""
    a = analyse(EQUALITY, {"motor_kw": 75.0}, {"range_km": 250.0 + 1e-9})
    assert [(e["name"], e["kind"]) for e in a["active_constraints"]] == [("range_km", "equal")]
    assert a["lines"] == ["active: range_km == 250 km, margin 0 km"]
    off = analyse(EQUALITY, {"motor_kw": 75.0}, {"range_km": 250.2})  # 8e-4 of 250 over: violated, not also active
    assert off["active_constraints"] == [] and [(e["kind"], e["violation"]) for e in off["violated"]] == [
        ("equal", pytest.approx(0.2))]
    assert off["lines"] == ["violated: range_km == 250 km is 250.2 km, over by 0.2 km"]
    jac = {"range_km": {"motor_kw": -1.0}}
    short = analyse(EQUALITY, {"motor_kw": 40.0}, {"range_km": 249.0}, jacobian=jac)  # more range: lower motor_kw
    assert short["violated"][0]["blocked_by"][0]["variable"] == "motor_kw"
    assert short["lines"][0] == "violated: range_km == 250 km is 249 km, short by 1 km"


def test_the_terminal_shows_an_active_equality_once_with_its_net_multiplier():
    import io

    from bev_mdo.cli.optimize import _verdict

    fo = {"verdict": "optimum", "stationarity": 1e-9, "complementarity": 0.0, "tolerance": 1e-4,
          "cost": {"points": 0, "wall_time_s": 0.0}, "active_bounds": [], "equalities": [],
          "active_constraints": [{"name": "lift >= 0.5", "multiplier": 1.847},
                                 {"name": "lift <= 0.5", "multiplier": 0.0}]}
    result = {"first_order": fo, "verdict": "optimum", "design": {},
              "constraints": {"lift": {"value": 0.5, "lower": 0.5, "upper": 0.5, "margin": 0.0}}}
    out = io.StringIO()
    _verdict(result, out, {})
    assert [ln.strip() for ln in out.getvalue().splitlines() if "lift" in ln] == [
        "active: lift == 0.5, margin 0, multiplier -1.847"]


def test_a_dimensionless_quantity_has_no_unit_after_its_number():
    """'g <= -1 – is 9.58e-13 –': the en dash printed for a dimensionless unit read as a minus sign."""
    problem = Problem.from_config({"objective": "f", "design_variables": {"x": {"lower": 0, "upper": 1}},
                                   "constraints": {"g": {"upper": -1}}})
    units = {"f": "1", "g": "-", "x": ""}
    a = active.analyse(problem, {"x": 0.0}, {"g": 0.5}, units=units)
    assert a["lines"][0].startswith("violated: g <= -1 is 0.5, over by 1.5"), a["lines"]
    assert not any("–" in line for line in a["lines"]), a["lines"]
    a = active.analyse(problem, {"x": 0.0}, {"g": -1.0}, units=units)
    assert "active: g <= -1, margin 0" in a["lines"] and "on its lower bound: x = 0 (bound 0, margin 0)" in a["lines"]


def test_a_design_outside_its_bounds_is_named_and_is_not_feasible():
    """COBYLA ended 6.5 % above a motor's upper bound and 8.5 % below a battery's lower one; the answers named
    the violated constraints only, valued there, nearer their limits than any design inside the bounds."""
    a = analyse(PROBLEM, {"motor_kw": 127.8, "battery_kwh": 18.3}, {"range_km": 300.0, "accel_time_0_100_s": 9.0})
    assert not a["feasible"] and a["violated"] == []
    assert [(b["name"], b["kind"], b["by"]) for b in a["outside_bounds"]] == [
        ("motor_kw", "upper", pytest.approx(7.8)), ("battery_kwh", "lower", pytest.approx(1.7))]
    assert a["lines"][0].startswith("outside its bounds: motor_kw = 127.8 kW, above its upper bound 120 kW by 7.8 kW")
    inside = analyse(PROBLEM, {"motor_kw": 120.0 + 1e-9, "battery_kwh": 25.0}, {"range_km": 300.0, "accel_time_0_100_s": 9.0})
    assert inside["feasible"] and inside["outside_bounds"] == []  # within the run's tolerance


def test_a_kink_is_no_free_way_out_of_an_unreachable_limit():
    """A top speed of 400 km/h, out of reach within the bounds, ended where the motor-speed cap (falling with
    the gear) meets the power limit (free of it): the gear's one-sided slope into the cap said "a first-order step
    reduces it: the optimiser stopped short". Both sides counted, the motor's upper bound blocks it."""
    import yaml

    from bev_mdo import Study
    from bev_mdo.config import resolve_disciplines
    from bev_mdo.mdo.active import answers_for
    from bev_mdo.testing import REPO

    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed",
                          {"name": "top_speed", "class": "examples.top_speed:TopSpeed"}]
    raw["search_path"] = [str(REPO)]
    raw["problem"]["constraints"]["top_speed_kmh"] = {"lower": 400}
    study = Study(raw)

    def point(gear):
        design = {"motor_kw": 120.0, "gear_ratio": gear, "battery_kwh": 30.0}  # the most power (the pack's: 120.4 kW)
        return design, study.evaluate(design, transport="inprocess").outputs
    power_limited = point(3.0)[1]["top_speed_kmh"]  # above the torque's reach (base speed) and below the cap
    capped = point(11.0)[1]["top_speed_kmh"]  # cap x gear is the same for every gear
    design, values = point(11.0 * capped / power_limited)  # where the two meet
    ans = answers_for(study.config.settings, design, values, lambda: resolve_disciplines(study.config), units=UNITS)
    (v,) = ans["violated"]
    assert v["name"] == "top_speed_kmh" and not v["free_way"]
    assert [b["variable"] for b in v["blocked_by"]][0] == "motor_kw"
    assert not any("stopped short" in line for line in ans["lines"])


def test_a_step_the_bounds_cut_short_is_no_promise_of_feasibility():
    """A battery sized for its range (a docs trial): the pack limited the 0-100 km/h time at 10.56 s, a grid of
    2,501 designs had none feasible, yet the answers said "a first-order step reduces it ...: the optimiser stopped
    short". The step ran over the motor's whole range from 0.2 % below its upper bound. Now a step stops at the
    bounds, and one that does not reach the limit says so."""
    point = {"motor_kw": 119.835, "battery_kwh": 25.0}
    jac = {"accel_time_0_100_s": {"motor_kw": -0.005, "battery_kwh": 0.0}, "range_km": {"motor_kw": 0.0,
                                                                                       "battery_kwh": 8.0}}
    (v,) = analyse(PROBLEM, point, {"range_km": 260.0, "accel_time_0_100_s": 10.56}, jacobian=jac)["violated"]
    assert v["free_way"] and v["free_way_reduction"] == pytest.approx(0.005 * 0.165)  # to 120 kW, not 40 kW more
    text = "\n".join(summary_lines(analyse(PROBLEM, point, {"range_km": 260.0, "accel_time_0_100_s": 10.56},
                                           jacobian=jac)))
    assert "reduces it by at most 0.000825 s" in text and "the end is near a least violation; other start points" in text
    assert "stopped short" not in text
    # room enough: the step removes it, and the optimiser stopped short
    (v,) = analyse(PROBLEM, {"motor_kw": 100.0, "battery_kwh": 25.0}, {"range_km": 260.0, "accel_time_0_100_s": 10.05},
                   jacobian=jac)["violated"]
    assert v["free_way_reduction"] == pytest.approx(0.1) and v["free_way_reduction"] >= v["violation"]


def test_a_margin_of_zero_has_no_sign():
    """golinski's optimize --json had "margin": -0.0 where a constraint's value met its upper limit exactly."""
    import math

    a = analyse(PROBLEM, {"motor_kw": 75.0, "battery_kwh": 25.0}, {"range_km": 300.0, "accel_time_0_100_s": 10.0})
    (e,) = a["active_constraints"]
    assert e["margin"] == 0.0 and math.copysign(1.0, e["margin"]) == 1.0
