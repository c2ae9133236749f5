"""A misspelt name given to the Python API (a design, a fixed value, an objective, --at, --wrt) is refused
with the nearest known name, as --bound and --constraint were: these listed 30-odd names and no hint."""
from pathlib import Path

import pytest

from bev_mdo import Study
from bev_mdo.api.errors import InputError

LEAF = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"


@pytest.mark.parametrize("call, near", [
    (lambda s: s.evaluate({"motor_kww": 80.0}, transport="inprocess"), "motor_kw"),
    (lambda s: s.sweep(designs={"motor_kww": [80.0, 90.0]}, transport="inprocess"), "motor_kw"),
    (lambda s: s.sweep(doe="lhs", samples=4, fixed={"gear_ratoi": 8.0}, transport="inprocess"), "gear_ratio"),
    (lambda s: s.sensitivity(wrt=["battery_kwhh"], transport="inprocess"), "battery_kwh"),
    (lambda s: s.sensitivity(at={"glider_kgg": 1000.0}, transport="inprocess"), "glider_kg"),
    (lambda s: s.pareto(objectives=["energy_wh_per_km", "powertrain_cost"], pop=4, generations=1,
                        transport="inprocess"), "powertrain_cost_usd"),
])
def test_an_unknown_name_gets_the_nearest_one(call, near):
    with pytest.raises(InputError, match=rf"did you mean '{near}'\?"):
        call(Study(LEAF))


def test_a_name_like_none_gets_no_guess():
    with pytest.raises(InputError) as exc:
        Study(LEAF).evaluate({"zzzz": 1.0}, transport="inprocess")
    assert "did you mean" not in str(exc.value) and "design variables" in str(exc.value)
