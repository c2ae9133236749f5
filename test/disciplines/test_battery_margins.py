"""The energy discipline's battery margins (option feasibility_outputs, quasi_static): a pack too small for
the cycle is capped at ocv^2/4R and runs below 0 % SOC, so its energy per km leaves out what it did not
deliver (a 1 kWh pack: about 60 Wh/km on the NEDC against 106 for 24 kWh) and an optimiser minimising energy
picked it; battery_power_margin_kw and battery_soc_margin >= 0 keep it from such a pack."""
import copy
from pathlib import Path

import numpy as np
import pytest
import yaml

from bev_mdo.config import RunConfig
from bev_mdo.models import topology as tp
from bev_mdo.models.cycles import load_cycle, resample

ROOT = Path(__file__).resolve().parents[2]
WEIGHTS = {"nedc": 0.4, "wltc_class3": 0.6}


def _energy(topology, feasibility_outputs=True):
    raw = yaml.safe_load((ROOT / "config" / "topologies_artemis.yaml").read_text())
    raw["vehicle"]["topology"] = topology
    for name in ("drive_torque_margin_nm", "motor_speed_margin_rad_s"):  # constrainable only with the option
        del raw["problem"]["constraints"][name]
    raw["disciplines"][1] = {"name": "energy", "options": {"feasibility_outputs": feasibility_outputs,
                                                           "cycle_weights": WEIGHTS}}
    if topology in ("DM-DA", "IWM-DA"):
        raw["problem"]["design_variables"]["motor_rear_kw"] = {"lower": 20, "upper": 65, "initial": 40}
    if topology == "DM-DA":
        raw["problem"]["design_variables"]["gear_ratio_rear"] = {"lower": 4, "upper": 9.4, "initial": 7.9}
    if topology.startswith("IWM"):
        del raw["problem"]["design_variables"]["gear_ratio"]
    return next(d for d in RunConfig.load(raw).disciplines if d.name == "energy")


@pytest.mark.parametrize("topology", tp.TOPOLOGIES)
def test_the_battery_margins_are_the_tightest_over_the_cycles(topology):
    energy = _energy(topology)
    assert energy.outputs[-3:] == ("battery_power_margin_kw", "battery_soc_margin", "battery_current_margin")
    t = tp.get_topology(topology)
    x = {"vehicle_mass_kg": np.array([1500.0, 1500.0]), "motor_kw": np.array([80.0, 80.0]) / t.front_motors,
         "battery_kwh": np.array([1.0, 24.0])}
    if t.geared:
        x["gear_ratio"] = np.array([8.0, 8.0])
    if t.two_axles:
        x["motor_rear_kw"] = np.array([40.0, 40.0]) / t.rear_motors
        if t.geared:
            x["gear_ratio_rear"] = np.array([8.0, 8.0])
    out = energy.compute(x)
    p = {**energy.extra, **energy._params(x)}
    runs = [tp.simulate(resample(load_cycle(c)), p, t, x["vehicle_mass_kg"], x["motor_kw"], x["battery_kwh"],
                        x.get("gear_ratio"), x.get("motor_rear_kw"), x.get("gear_ratio_rear")) for c in WEIGHTS]
    np.testing.assert_array_equal(out["battery_power_margin_kw"],
                                  np.minimum(runs[0].battery_power_margin_kw, runs[1].battery_power_margin_kw))
    np.testing.assert_array_equal(out["battery_soc_margin"], np.minimum(runs[0].soc_min, runs[1].soc_min) - 0.05)
    np.testing.assert_array_equal(out["battery_current_margin"],
                                  np.minimum(runs[0].battery_current_margin, runs[1].battery_current_margin))
    # 1 kWh cannot deliver either cycle: asked for more than it can give and run below empty; 24 kWh can
    assert out["battery_power_margin_kw"][0] < -20 < 20 < out["battery_power_margin_kw"][1]
    assert out["battery_soc_margin"][0] < -0.05 < 0.3 < out["battery_soc_margin"][1]
    assert out["battery_current_margin"][0] < -1 < 0.5 < out["battery_current_margin"][1] < 1
    plain = _energy(topology, feasibility_outputs=False)  # the default outputs: unchanged, no margins
    assert plain.outputs == ("energy_wh_per_km", "energy_wall_wh_per_km")
    np.testing.assert_array_equal(plain.compute(x)["energy_wh_per_km"], out["energy_wh_per_km"])


def test_an_optimiser_minimising_energy_does_not_end_at_a_pack_that_cannot_deliver_the_cycle():
    """leaf_nedc on the quasi-static model without its range constraint, the battery from 1 kWh: a smaller pack
    is lighter, and below about 4.6 kWh it delivers less than the NEDC asks, so the energy per km falls
    further. SLSQP ends at 1 kWh (58 Wh/km, 31 kW short, SOC down to -0.31); with the battery margins
    constrained >= 0 it ends at a pack that delivers the cycle. (The 0-100 km/h time's battery limit is off
    here: with it, the 10 s constraint alone keeps the pack at 21.7 kWh.)"""
    from bev_mdo.mdo.driver import run_optimization
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    raw = yaml.safe_load((ROOT / "config" / "leaf_nedc.yaml").read_text())
    raw["energy_model"] = "quasi_static"
    raw["vehicle"]["battery_to_shaft_efficiency"] = 0.0
    raw["disciplines"] = ["vehicle_mass", {"name": "energy", "options": {"feasibility_outputs": True}}, "range",
                          "acceleration", "motor_speed", "cost"]
    raw["problem"]["design_variables"]["battery_kwh"].update(lower=1.0)
    del raw["problem"]["constraints"]["range_km"]
    ends = {}
    for constrained in (False, True):
        r = copy.deepcopy(raw)
        if constrained:
            r["problem"]["constraints"].update(battery_power_margin_kw={"lower": 0}, battery_soc_margin={"lower": 0})
        cfg = RunConfig.load(r)
        ends[constrained] = run_optimization(cfg.settings, InProcessEvaluator(cfg.disciplines))
    short = ends[False]
    assert short.design["battery_kwh"] < 1.1 and short.outputs["battery_power_margin_kw"] < -20
    assert short.outputs["battery_soc_margin"] < -0.2
    res = ends[True]
    assert res.feasible and res.design["battery_kwh"] > 4.0
    assert res.outputs["battery_power_margin_kw"] > -1e-3 and res.outputs["battery_soc_margin"] > -1e-4
    assert res.outputs["energy_wh_per_km"] > 1.5 * short.outputs["energy_wh_per_km"]
