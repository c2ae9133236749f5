"""The topology study's ranking and its caveats (studies.topologies.ranking / caveats): a topology
ranking printed from fronts must say what it rests on, a 0-100 km/h time the tyres cannot carry and a
parameter set not calibrated to measured cars."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

from bev_mdo.config import RunConfig
from bev_mdo.studies.topologies import caveats, config_for_topology, ranking, ranking_lines

ARTEMIS = Path(__file__).resolve().parents[2] / "config" / "topologies_artemis.yaml"


def _front(energy, accel, design=None):
    design = design or {"motor_kw": [20.0] * len(energy), "battery_kwh": [24.0] * len(energy)}
    return SimpleNamespace(names=list(design), X=np.array(list(design.values())).T, values={"energy_wh_per_km": np.array(energy),
                                                                "accel_time_0_100_s": np.array(accel)})


def _configs(parameter_set, **vehicle):
    raw = yaml.safe_load(ARTEMIS.read_text())
    raw["vehicle"]["parameter_set"] = parameter_set
    if parameter_set is None:
        del raw["vehicle"]["parameter_set"]
    raw["vehicle"].update(vehicle)
    return {t: RunConfig.load(config_for_topology(raw, t)) for t in ("SM-SA", "IWM-SA", "IWM-DA")}


def test_ranking_orders_each_objective_by_its_fronts_best_and_leaves_out_an_empty_front():
    results = {"SM-SA": _front([125.0, 130.0], [6.0, 5.9]), "IWM-DA": _front([115.0, 120.0], [2.4, 2.3]),
               "IWM-SA": SimpleNamespace(X=np.ones((0, 1)), values={})}
    ranked = ranking(results, [("energy_wh_per_km", False), ("accel_time_0_100_s", False)])
    assert [r["topology"] for r in ranked["energy_wh_per_km"]] == ["IWM-DA", "SM-SA"]
    assert ranked["energy_wh_per_km"][1]["change_pct"] == pytest.approx(100 * (125 / 115 - 1))
    assert ranked["accel_time_0_100_s"][0] == {"topology": "IWM-DA", "best": 2.3, "unit": "s", "change_pct": 0.0}
    lines = ranking_lines(ranked)
    assert lines[0] == "ranking by each front's best energy_wh_per_km (Wh/km): IWM-DA 115.0, SM-SA 125.0 (+8.7 %)"
    maxed = ranking(results, [("energy_wh_per_km", True)])["energy_wh_per_km"]
    assert [r["topology"] for r in maxed] == ["SM-SA", "IWM-DA"] and maxed[0]["best"] == 130.0


def test_a_time_faster_than_the_grip_allows_and_the_thesis_set_are_caveats():
    """With tyre_grip_coefficient 0 (the thesis set) IWM-DA's front reached 2.36 s 0-100 km/h, under the
    2.83 s mu = 1 allows on four driven wheels (100/3.6 / 9.81), and nothing said so; IWM-SA (one driven
    axle, 60 % of the weight) cannot beat 4.72 s. SM-SA's 5.9 s is within its grip."""
    results = {"SM-SA": _front([125.0], [5.9]), "IWM-SA": _front([121.0], [3.6]), "IWM-DA": _front([115.0], [2.36])}
    lines = caveats(results, _configs("thesis"))
    assert len(lines) == 2  # at most 80 kW of motors on 24 kWh: within what the pack gives (96 kW at the shafts)
    assert "IWM-SA 3.60 s (at least 4.72 s with 60 % of the weight on the driven axle)" in lines[0]
    assert "IWM-DA 2.36 s (at least 2.83 s with every wheel)" in lines[0] and "SM-SA" not in lines[0]
    assert lines[-1].startswith("caveat: SM-SA, IWM-SA, IWM-DA ran on the thesis' efficiency map (motor_loss_model 0")
    assert caveats({"SM-SA": _front([125.0], [5.9])}, _configs("thesis"))[0].startswith("caveat: SM-SA ran on")


def test_a_calibrated_set_with_the_grip_on_has_no_caveat():
    results = {"SM-SA": _front([125.0], [5.9]), "IWM-DA": _front([115.0], [2.36])}
    assert caveats(results, _configs("epa2022_quasi_static")) == []


def test_motors_rated_above_the_battery_s_discharge_limit_are_a_caveat():
    """Every IWM-DA front design of the thesis study (battery limit off) had more motor than its pack gives
    at 5 C (368 kW on 21.6 kWh: 87 kW at the shafts), and nothing said so."""
    results = {"SM-SA": _front([125.0], [5.9], {"motor_kw": [95.0], "battery_kwh": [24.0]}),
               "IWM-DA": _front([115.0, 116.0], [2.45, 3.0], {"motor_kw": [92.0, 20.0], "motor_rear_kw": [92.0, 20.0],
                                                              "battery_kwh": [21.6, 24.0]})}
    line = next(x for x in caveats(results, _configs("thesis")) if "battery_to_shaft_efficiency 0" in x)
    assert "IWM-DA 1 of 2 (the most over its pack: 368 kW of motors on 21.6 kWh, which gives 87 kW)" in line
    assert "SM-SA" not in line  # 95 kW on 24 kWh: 96 kW
    limited = _configs("epa2022_quasi_static")  # the limit on: the times respect the pack, no caveat
    assert not [x for x in caveats(results, limited) if "pack" in x]


def test_the_uncalibrated_map_is_a_caveat_with_or_without_the_thesis_set():
    """Without a parameter set the study runs the same thesis map (identical fronts), yet the caveat named
    the set, not the model, and went away."""
    results = {"SM-SA": _front([125.0], [5.9])}
    plain = caveats(results, _configs(None))
    assert plain == ["caveat: SM-SA ran on the thesis' efficiency map (motor_loss_model 0: the thesis set or no set), "
                     "not calibrated to measured cars: it over-predicts the energy differences between variants of one "
                     "car (docs/validation.md, pairs), so this energy ranking is the thesis model's, not a measured car's"]
    assert caveats(results, _configs("thesis", motor_loss_model=1.0, tyre_grip_coefficient=1.0,
                                     battery_to_shaft_efficiency=0.9)) == []
