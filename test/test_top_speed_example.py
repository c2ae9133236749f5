"""The README's example of a discipline of your own (examples/top_speed.py): the vehicle constants it
reads are its parameters, so a run that overrides one (--set, --vary, --wrt) changes its answer too."""
from __future__ import annotations

import pytest
import yaml

from bev_mdo.api import Study
from bev_mdo.testing import REPO


@pytest.fixture(scope="module")
def study():
    config = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8"))
    config["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                             {"name": "top_speed", "class": "examples.top_speed:TopSpeed",
                              "options": {"motor_max_speed_rad_s": 1100}}]
    config["search_path"] = [str(REPO)]
    config["problem"]["constraints"]["top_speed_kmh"] = {"lower": 140}
    return Study(config)


def test_a_swept_wheel_radius_reaches_the_top_speed(study):
    # at 80 kW and 8:1 the top speed is the gear's, omega_max r_w / i_g: 1100 x 0.3 / 8 m/s = 148.5 km/h
    # (the example read r_w from the config alone and gave 156.42 km/h, the config's 0.316 m, for both)
    r = study.sweep(designs={"wheel_radius_m": [0.3, 0.4]}, transport="inprocess")
    assert r.ok.all()
    assert r.outputs["top_speed_kmh"] == pytest.approx([1100 * 0.3 / 8 * 3.6, 1100 * 0.4 / 8 * 3.6], rel=1e-9)
    assert r.outputs["motor_speed_max_rad_s"][0] > r.outputs["motor_speed_max_rad_s"][1]  # the built-in follows too


def test_the_top_speeds_sensitivity_to_the_wheel_radius_is_one_where_the_gear_limits_it(study):
    s = study.sensitivity(wrt=["wheel_radius_m", "drag_area_m2"], order=1, transport="inprocess").to_dict()
    assert s["wrt"] == ["wheel_radius_m", "drag_area_m2"]
    # normalised (r/v) dv/dr of v = omega_max r / i_g is 1 (the example gave 0); the power balance does not bind
    assert s["first_order"]["top_speed_kmh"]["normalised"] == pytest.approx([1.0, 0.0], abs=1e-6)


def test_with_a_coast_down_the_top_speed_balances_that_road_load():
    """The example ignored `vehicle.road_load` and balanced the power against the thesis' drag and rolling
    terms, while every built-in model of the run took the coast-down: two road loads in one vehicle."""
    from scipy.optimize import brentq

    config = yaml.safe_load((REPO / "config" / "leaf_epa_combined.yaml").read_text(encoding="utf-8"))
    config["disciplines"] += [{"name": "top_speed", "class": "examples.top_speed:TopSpeed",
                               "options": {"motor_max_speed_rad_s": 5000}}]  # power-limited, not the gear
    config["search_path"] = [str(REPO)]
    r = Study(config).sweep(designs={"motor_kw": [40.0, 80.0], "gear_ratio": [2.0, 2.0]}, transport="inprocess")
    assert r.ok.all()
    rl = config["vehicle"]["road_load"]
    for kw, mass, v_kmh in zip([40.0, 80.0], r.outputs["vehicle_mass_kg"], r.outputs["top_speed_kmh"]):
        force = rl["a_n"] * mass / rl["mass_kg"]  # A scales with the mass (road_load.py)
        envelope = lambda v: min(3.5 * kw * 0.97 * 2.0 / 0.316, kw * 1e3 * 0.97 / v)  # torque, then power
        v = brentq(lambda v: force + rl["b_n_per_m_s"] * v + rl["c_n_per_m2_s2"] * v * v - envelope(v),
                   1.0, 200.0, xtol=1e-12)
        assert v_kmh == pytest.approx(v * 3.6, rel=1e-9)


def test_at_a_long_gear_the_top_speed_is_where_the_torque_meets_the_road_load():
    """A Kona trial: at 0.5:1 the example gave 244 km/h and the constraint "met", from the peak power alone,
    while the motor stays below its base speed and its 280 Nm give 429 N at the wheels (the acceleration model
    took 189 s to reach 100 km/h). The force is the motor's envelope, torque up to the base speed."""
    from scipy.optimize import brentq

    config = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8"))
    config["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                             {"name": "top_speed", "class": "examples.top_speed:TopSpeed"}]
    config["search_path"] = [str(REPO)]
    config["problem"]["design_variables"]["gear_ratio"]["lower"] = 0.5
    r = Study(config).sweep(designs={"gear_ratio": [0.5, 8.0]}, transport="inprocess")
    v = config["vehicle"]
    mass = r.outputs["vehicle_mass_kg"][0]
    force_n = 3.5 * 80.0 * 0.5 * v["gear_efficiency"] / v["wheel_radius_m"]  # 280 Nm through 0.5:1
    load = lambda s: (0.5 * v["air_density_kg_m3"] * v["drag_area_m2"] * s * s
                      + v["rolling_resistance"] * mass * v["gravity_m_s2"])
    expected = brentq(lambda s: load(s) - force_n, 1.0, 100.0, xtol=1e-12) * 3.6
    assert r.outputs["top_speed_kmh"][0] == pytest.approx(expected, rel=1e-9)
    assert r.outputs["top_speed_kmh"][0] < 110.0  # not 244


@pytest.mark.parametrize("name", ["drag_area_m2", "rolling_resistance", "air_density_kg_m3"])
@pytest.mark.parametrize("with_example", [True, False])
def test_with_a_coast_down_a_constant_it_leaves_unused_is_not_overridable(name, with_example):
    """A Kona-like run with a coast-down and the example beside it took --set drag_area_m2=1.5 as a parameter
    and gave the same energy, a sensitivity of 0 and a sweep of identical rows (the example offered the thesis'
    terms the coast-down replaces; the built-in models offered the air density): refused, one line."""
    config = yaml.safe_load((REPO / "config" / "leaf_epa_combined.yaml").read_text(encoding="utf-8"))
    if with_example:
        config["disciplines"] += [{"name": "top_speed", "class": "examples.top_speed:TopSpeed"}]
        config["search_path"] = [str(REPO)]
    study = Study(config)
    with pytest.raises(ValueError, match=f"{name}: neither a design variable nor a discipline parameter"):
        study.evaluate({name: 1.0}, transport="inprocess")
    with pytest.raises(ValueError, match=name):
        study.sensitivity(wrt=[name], order=1, transport="inprocess")


def test_with_two_speeds_the_gear_cap_is_the_longer_gears():
    """The example capped the top speed by the first gear alone: a two-speed van was held at 117 km/h where
    its second gear reaches 235, and its optimum pinned by a top-speed limit the car meets."""
    config = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8"))
    config["vehicle"].update(gear_count=2, gear_ratio_2=4.7)
    config["problem"]["design_variables"]["gear_ratio"]["lower"] = 4.7  # the second gear no shorter (load checks)
    config["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                             {"name": "top_speed", "class": "examples.top_speed:TopSpeed",
                              "options": {"motor_max_speed_rad_s": 600}}]
    config["search_path"] = [str(REPO)]
    r = Study(config).sweep(designs={"gear_ratio": [11.0, 8.0]}, transport="inprocess")
    # the second gear's cap whatever the first (11: 62 km/h); a first gear longer than the second is refused on load
    assert r.outputs["top_speed_kmh"] == pytest.approx([600 * 0.316 / 4.7 * 3.6] * 2, rel=1e-9)


def test_without_the_option_the_speed_limit_is_the_vehicles_one():
    # a user trial: the option and vehicle.motor_speed_limit_rpm were one limit entered twice, never compared
    config = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8"))
    config["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                             {"name": "top_speed", "class": "examples.top_speed:TopSpeed"}]
    config["search_path"] = [str(REPO)]
    config["vehicle"]["motor_speed_limit_rpm"] = 9000.0
    r = Study(config).sweep(designs={"gear_ratio": [8.0, 8.0], "motor_speed_limit_rpm": [9000.0, 12000.0]},
                            transport="inprocess")
    assert r.ok.all()
    assert r.outputs["top_speed_kmh"] == pytest.approx([w * 3.14159265358979 / 30 * 0.316 / 8 * 3.6
                                                         for w in (9000.0, 12000.0)], rel=1e-9)


def test_where_the_pack_gives_less_than_the_motor_the_top_speed_is_the_packs():
    """A review trial: at 120 kW, 3:1 and 20 kWh the example gave 233.5 km/h from the motor's 120 kW beside the note
    that the pack gives 80.3 kW at the shaft; the pack's limit (as the acceleration model takes it) holds here too."""
    from scipy.optimize import brentq

    from bev_mdo.models.acceleration import battery_shaft_power_w
    from bev_mdo.models.params import validate_vehicle

    config = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text(encoding="utf-8"))
    config["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                             {"name": "top_speed", "class": "examples.top_speed:TopSpeed"}]
    config["search_path"] = [str(REPO)]
    r = Study(config).evaluate({"motor_kw": 120.0, "gear_ratio": 3.0, "battery_kwh": 20.0}, transport="inprocess")
    v = config["vehicle"]
    shaft_w = battery_shaft_power_w(20.0, validate_vehicle(v))
    assert 80e3 < shaft_w < 81e3
    mass = r.outputs["vehicle_mass_kg"]
    load = lambda s: (0.5 * v["air_density_kg_m3"] * v["drag_area_m2"] * s * s
                      + v["rolling_resistance"] * mass * v["gravity_m_s2"]) * s
    expected = brentq(lambda s: load(s) - shaft_w * v["gear_efficiency"], 1.0, 100.0, xtol=1e-12) * 3.6
    assert r.outputs["top_speed_kmh"] == pytest.approx(expected, rel=1e-9)
    assert r.outputs["top_speed_kmh"] < 210.0  # not 233.5


def test_a_two_motor_vehicle_is_told_that_only_its_front_motor_counts():
    """An AWD trial: a Kia EV6 (74 + 165 kW, DM-DA) read 178.9 km/h, its front motor's alone, with no word."""
    import warnings

    from bev_mdo.models.cycles import CycleNote
    from examples.top_speed import TopSpeed

    options = TopSpeed.Options()
    with pytest.warns(CycleNote, match=r"^top_speed \(examples/top_speed.py\) counts one motor and its gear: of a "
                                       r"DM-DA vehicle the front motor alone \(motor_kw, gear_ratio\)$"):
        TopSpeed.from_config({"vehicle": {"topology": "DM-DA"}}, options)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        TopSpeed.from_config({"vehicle": {"topology": "SM-SA"}}, options)
