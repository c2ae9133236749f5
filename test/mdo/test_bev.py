"""The default BEV problem (thesis eq 7-32) through the engine, in process."""
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.optimize import brentq

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.driver import evaluate_design, run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator

LEAF = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"


@pytest.fixture(scope="module")
def config():
    return load_config(LEAF)


@pytest.fixture(scope="module")
def fd_config():
    """The default problem with whole-MDA finite differences (no discipline partials)."""
    raw = yaml.safe_load(LEAF.read_text())
    raw.setdefault("optimizer", {})["derivatives"] = "fd"
    return load_config(raw)


@pytest.fixture(scope="module")
def mdf(config):
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), formulation="mdf")


def test_mdf_and_idf_reach_the_same_optimum(config, mdf):
    idf = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), formulation="idf")
    assert mdf.success and idf.success and mdf.feasible and idf.feasible
    for k, v in mdf.design.items():
        assert idf.design[k] == pytest.approx(v, rel=1e-4), k
    assert idf.objective == pytest.approx(mdf.objective, rel=1e-7)
    # IDF: only the consistent start point, plus the final report's MDA
    assert idf.mda_evaluations == 2 < mdf.mda_evaluations


def test_optimum_is_on_the_active_constraints(mdf):
    # lighter battery is always better; acceleration and motor speed limits bind
    assert mdf.design["battery_kwh"] == pytest.approx(20.0, abs=1e-8)
    assert mdf.constraints["accel_time_0_100_s"]["margin"] == pytest.approx(0.0, abs=1e-6)
    assert mdf.constraints["motor_speed_max_rad_s"]["margin"] == pytest.approx(0.0, abs=1e-4)
    nominal = evaluate_design(load_config(LEAF), InProcessEvaluator(resolve_disciplines(load_config(LEAF))),
                              {"motor_kw": 80, "gear_ratio": 8, "battery_kwh": 24})
    assert mdf.objective < nominal["objective"]["value"]


def test_run_reports_counts_history_and_iteration_records(fd_config):
    records = []
    ev = InProcessEvaluator(resolve_disciplines(fd_config))
    res = run_optimization(fd_config, ev, callback=records.append)
    assert records == res.history and records[0]["iteration"] == 0
    assert [r["iteration"] for r in records] == list(range(len(records)))
    keys = {"iteration", "design", "objective", "constraints", "max_violation", "feasible", "formulation",
            "optimizer", "mda_evaluations", "discipline_evaluations", "wall_time_s", "objective_name"}
    assert keys <= set(records[-1])
    assert res.discipline_evaluations == {k: res.mda_evaluations for k in res.discipline_evaluations}
    assert res.iterations >= 1 and res.gradients >= res.iterations
    assert set(res.outputs) >= {"vehicle_mass_kg", "energy_wh_per_km", "range_km", "accel_time_0_100_s",
                                "motor_speed_max_rad_s", "powertrain_cost_usd"}


class _BatchLog(InProcessEvaluator):
    """Counts the points of every MDA request (the data-flow MDA calls evaluate_flow once per batch)."""

    def __init__(self, disciplines):
        super().__init__(disciplines)
        self.sizes: list[int] = []

    def evaluate_flow(self, names, request, n, partials=False):
        self.sizes.append(n)
        return None  # serve it wave by wave, as without the hook


@pytest.mark.parametrize("opt, first", [("SLSQP", 4), ("trust-constr", 4), ("COBYLA", 1)])
def test_x0_goes_with_its_stencil_for_gradient_based_optimizers(fd_config, opt, first):
    ev = _BatchLog(resolve_disciplines(fd_config))
    res = run_optimization(fd_config, ev, optimizer=opt)
    assert ev.sizes[0] == first  # x0 (+ its 3 FD points when the first step needs the gradient there)
    if first > 1:
        # every batch is a point with its stencil: one per gradient, and no point evaluated twice
        check = res.first_order["cost"]  # the end-point check's own batch (its steps either side for a kink)
        assert res.batches - check["batches"] == len(ev.sizes) - check["batches"] == res.gradients
        assert res.mda_evaluations - check["points"] == sum(ev.sizes) - check["points"] == 4 * res.gradients


@pytest.mark.parametrize("opt", ["trust-constr", "COBYQA", "COBYLA", "differential_evolution"])
def test_every_optimizer_finds_the_mdf_optimum(config, mdf, opt):
    res = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), optimizer=opt)
    assert res.feasible
    for k, v in mdf.design.items():
        assert res.design[k] == pytest.approx(v, rel=1e-4), k
    assert res.objective == pytest.approx(mdf.objective, rel=1e-6)


def sized_config(method="gauss_seidel", **vehicle):
    raw = yaml.safe_load(LEAF.read_text())
    raw["problem"]["battery_sized_for_range"] = True
    raw["mda"]["method"] = method
    raw["vehicle"].update(vehicle)
    return load_config(raw)


@pytest.mark.parametrize("method", ["gauss_seidel", "jacobi"])
def test_battery_sized_loop_matches_a_direct_fixed_point_solve(method):
    cfg = sized_config(method)
    assert "battery_kwh" not in cfg["problem"]["design_variables"]
    discs = {d.name: d for d in resolve_disciplines(cfg)}
    ev = InProcessEvaluator(discs.values())
    out = evaluate_design(cfg, ev, {"motor_kw": 80.0, "gear_ratio": 8.0})
    assert out["ok"] and out["mda_iterations"] > 2

    def residual(b):
        m = discs["vehicle_mass"].compute({"motor_kw": np.array([80.0]), "battery_kwh": np.array([b])})
        e = discs["energy"].compute({**m, "gear_ratio": np.array([8.0])})
        return b - discs["battery_sizing"].compute(e)["battery_kwh"][0]

    b_star = brentq(residual, 1.0, 200.0, xtol=1e-14)
    assert out["outputs"]["battery_kwh"] == pytest.approx(b_star, rel=1e-9)
    assert out["outputs"]["range_km"] == pytest.approx(170.0, rel=1e-9)


def test_battery_sized_mode_optimises_in_both_formulations():
    """Without the 0-100 km/h battery limit: the pack sized for 170 km (17 kWh) gives 68 kW to the shafts at 5C,
    and with the limit no motor of the bounds reaches 100 km/h in 10 s (the problem is infeasible)."""
    held = sized_config()
    out = evaluate_design(held, InProcessEvaluator(resolve_disciplines(held)), {"motor_kw": 120.0, "gear_ratio": 7.1})
    assert out["outputs"]["battery_kwh"] < 17.5 and out["outputs"]["accel_time_0_100_s"] > 10.5
    cfg = sized_config(battery_to_shaft_efficiency=0.0)
    a = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), formulation="mdf")
    b = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), formulation="idf")
    assert a.feasible and b.feasible and set(a.design) == {"motor_kw", "gear_ratio"}
    for k in a.design:
        assert b.design[k] == pytest.approx(a.design[k], rel=1e-4)
    assert a.outputs["range_km"] == pytest.approx(170.0, rel=1e-8)
