"""An IDF run ending away from consistency says so first in its answers: its largest violation was a
consistency residual that "why the end point is infeasible" never named, and its objective (at the optimiser's
coupling values) stood beside outputs analysed through the design that gave another."""
from __future__ import annotations

from pathlib import Path

from bev_mdo.api.runbag import answers, inconsistent_lines
from bev_mdo.config import load_config

CONFIG = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"
DESIGN = {"motor_kw": 80.0, "gear_ratio": 8.0, "battery_kwh": 24.0}


def _result(residuals: dict[str, float], objective: float, analysed: float) -> dict:
    return {"objective_name": "energy_wh_per_km", "objective": objective, "feasibility_tolerance": 1e-4,
            "design": DESIGN, "outputs": {"energy_wh_per_km": analysed},
            "first_order": {"equalities": [{"name": f"{k} consistency", "value": v, "multiplier": 1.0}
                                           for k, v in residuals.items()]}}


def test_broken_consistency_is_named_with_what_it_means_for_the_numbers():
    lines = inconsistent_lines(_result({"vehicle_mass_kg": -0.493, "energy_wh_per_km": 5e-5}, 100.7, 140.738))
    assert lines[0] == ("not consistent: vehicle_mass_kg: the optimiser's coupling value is not what its discipline "
                        "computes there (residual 0.493, normalised)")
    assert len(lines) == 2 and "energy_wh_per_km 100.7 and its largest violation are at the optimiser's coupling " \
        "values; the design analysed through (the outputs shown) gives energy_wh_per_km 140.738" in lines[1]
    # the objectives agreeing to the digits shown: the residual's line alone
    assert len(inconsistent_lines(_result({"vehicle_mass_kg": 0.01}, 100.5, 100.5000001))) == 1
    assert inconsistent_lines(_result({"vehicle_mass_kg": 5e-5}, 100.7, 140.0)) == []  # within the tolerance
    assert inconsistent_lines({"objective": 1.0}) == []  # MDF: no equalities


def test_the_answers_of_an_inconsistent_end_put_it_first_and_are_not_feasible():
    config = load_config(str(CONFIG))
    from bev_mdo.api.evaluate import design as evaluate

    rep = evaluate(config, DESIGN, "inprocess")
    result = _result({"vehicle_mass_kg": -0.3}, 90.0, rep["outputs"]["energy_wh_per_km"])
    result["outputs"], result["constraints"] = rep["outputs"], rep["constraints"]
    ans = answers(config, result)
    assert ans["feasible"] is False and ans["lines"][0].startswith("not consistent: vehicle_mass_kg")
    consistent = answers(config, {**result, "first_order": {"equalities": []}})
    assert consistent["feasible"] is True and not any("consistent" in line for line in consistent["lines"])
