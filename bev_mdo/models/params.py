"""Model constants with units, defaults and physical ranges; validation of config sections.

Every model's parameters are specified here (``VEHICLE_SPECS``, the road load and the spec table of
each model with constants of its own); a model takes its defaults from these tables and from
nowhere else. Sits just above :mod:`common` in the models layer: it imports no model (only the
battery constants and the cycle interpolation names, two leaf modules).
"""
from __future__ import annotations

import math

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from . import battery as bt
from .common import allowed, check_array, check_keys, check_value, is_number
from .cycles import DEFAULT_METHOD, KMH, METHODS


@dataclass(frozen=True)
class ParamSpec:
    """One model constant: default value, allowed closed range [lower, upper], unit, meaning, and
    whether only whole numbers are allowed (a count or a switch)."""

    default: float
    lower: float
    upper: float
    unit: str
    description: str
    integer: bool = False


# Leaf glider: kerb 1521 kg (Appendix A) minus the eq 7-20/7-21 powertrain at 80 kW / 24 kWh
# (64.16 + 187.2 kg); load 69 kg makes M = 1590 kg at the nominal design, the thesis'
# "2012 model weight plus rotational inertia and loads" (§7.3, ch.5).
_GLIDER_KG = 1521.0 - (0.532 * 80 + 21.6) - 7.8 * 24

VEHICLE_SPECS: dict[str, ParamSpec] = {
    "air_density_kg_m3": ParamSpec(1.25, 0.5, 1.5, "kg/m^3", "air density (eq 5-13 uses 1.25)"),
    "gravity_m_s2": ParamSpec(9.81, 9.7, 9.9, "m/s^2", "gravitational acceleration"),
    "drag_area_m2": ParamSpec(0.6412, 0.05, 3.0, "m^2", "drag area C_d*A_f (Table 7-5)"),
    "rolling_resistance": ParamSpec(0.007, 0.0, 0.05, "-", "rolling resistance coefficient C_r (Table 7-5)"),
    "wheel_radius_m": ParamSpec(0.316, 0.1, 0.6, "m", "wheel radius r_w (Appendix A: 0.632 m tyre)"),
    "gear_efficiency": ParamSpec(0.97, 0.5, 1.0, "-", "average gearbox efficiency eta_g (Table 7-5)"),
    "motor_constant_nm_a": ParamSpec(0.4, 0.01, 10.0, "N*m/A", "DC motor constant K_m (Table 7-5)"),
    "motor_resistance_ohm": ParamSpec(0.02, 0.0, 1.0, "ohm", "motor resistance R (Table 7-5)"),
    "motor_inductance_h": ParamSpec(5e-4, 0.0, 0.1, "H", "motor inductance L (not given in ch.7; chosen)"),
    "regen_fraction": ParamSpec(0.4, 0.0, 1.0, "-", "share of braking power recovered r (eq 6-34; ch.5 nominal 40 %)"),
    "glider_kg": ParamSpec(_GLIDER_KG, 200.0, 5000.0, "kg", "gliding body mass M_B (eq 7-19)"),
    "load_kg": ParamSpec(69.0, 0.0, 5000.0, "kg", "load and rotational-inertia mass M_L (eq 7-19; a van's payload)"),
    "motor_kg_per_kw": ParamSpec(0.532, 0.0, 5.0, "kg/kW", "motor specific mass (eq 7-20)"),
    "motor_base_kg": ParamSpec(21.6, 0.0, 500.0, "kg", "motor mass offset (eq 7-20)"),
    "battery_kg_per_kwh": ParamSpec(7.8, 0.5, 50.0, "kg/kWh", "battery specific mass (eq 7-21)"),
    "kerb_reference_kg": ParamSpec(1521.0, 200.0, 5000.0, "kg", "kerb mass at the reference powertrain (ch.3)"),
    "reference_motor_kw": ParamSpec(80.0, 1.0, 1000.0, "kW", "reference motor power (ch.3)"),
    "reference_battery_kwh": ParamSpec(24.0, 1.0, 500.0, "kWh", "reference battery capacity (ch.3)"),
    "mass_compounding": ParamSpec(1.6, 1.0, 3.0, "-", "mass compounding factor (ch.3)"),
    "motor_torque_per_kw": ParamSpec(3.5, 0.5, 20.0, "N*m/kW", "peak torque per kW (280 Nm / 80 kW, Fig 2-9)"),
    "motor_speed_limit_rpm": ParamSpec(10500.0, 1000.0, 30000.0, "rpm", "motor speed limit (ch.3)"),
    "power_to_energy_ratio": ParamSpec(4.0, 0.1, 100.0, "1/h", "battery cell P/E ratio (eq 2-22)"),
    "battery_usable_fraction": ParamSpec(1.0, 0.1, 1.0, "-", "usable share of battery capacity for range"),
    # 0-100 km/h grip limit (acceleration.py, topology.py): drive force <= mu g M x the driven axles' share
    "tyre_grip_coefficient": ParamSpec(1.0, 0.0, 2.0, "-", "tyre-road friction coefficient mu of the 0-100 km/h "
                                       "grip limit (dry asphalt about 1; 0 = no limit, the thesis)"),
    "driven_axle_load_share": ParamSpec(0.6, 0.2, 0.8, "-", "static share of the weight on the driven axle of a "
                                        "single-axle drive (front drive about 0.6; two driven axles carry all)"),
    # 0-100 km/h battery limit (acceleration.py, topology_accel.py): motors' shaft power <= pack power x this
    "battery_to_shaft_efficiency": ParamSpec(0.90, 0.0, 1.0, "-", "motor + inverter efficiency at full load "
                                             "from the pack's terminals to the motors' shafts in the 0-100 km/h "
                                             "run (an assumption, not from the thesis; 0 = no battery limit, "
                                             "the thesis)"),
}

# topology (thesis ch.4): one setting for every topology discipline (vehicle_mass, energy,
# cycle_range, acceleration, cost); any case, e.g. iwm-sa (topology_name)
VEHICLE_CHOICES: dict[str, tuple[str, ...]] = {"mass_model": ("ch7", "compounding"),
                                               "topology": ("SM-SA", "DM-DA", "IWM-SA", "IWM-DA")}

CYCLE_SPECS: dict[str, ParamSpec] = {
    "dt_s": ParamSpec(1.0, 0.01, 10.0, "s", "resampling step"),
}
# the single motor's options, SM-SA only (DM-DA has two axles by design, the in-wheel topologies their
# motors); refused with 2 on the other topologies at config load and at model entry (topology.py)
SM_SA_ONLY = {"gear_count": "a two-speed gearbox", "driven_axles": "the single-motor drive on two axles"}


def check_sm_sa_only(topology: str, values: Mapping[str, Any], where: str = "") -> None:
    """ValueError if ``values`` set an :data:`SM_SA_ONLY` option to 2 on a topology other than SM-SA."""
    for k, what in SM_SA_ONLY.items():
        if topology != "SM-SA" and np.any(np.asarray(values.get(k, 1.0)) == 2.0):
            raise ValueError(f"{where}{k}: 2 ({what}) is SM-SA only, not {topology}")


# coast-down road load (road_load.py): section key -> (flat parameter name, spec)
ROAD_LOAD_SPECS: dict[str, tuple[str, ParamSpec]] = {
    "a_n": ("road_load_a_n", ParamSpec(0.0, 0.0, 5000.0, "N", "constant road-load term A")),
    "b_n_per_m_s": ("road_load_b_n_per_m_s", ParamSpec(0.0, -100.0, 100.0, "N/(m/s)", "linear term B")),
    "c_n_per_m2_s2": ("road_load_c_n_per_m2_s2", ParamSpec(0.0, 0.0, 5.0, "N/(m/s)^2", "quadratic term C")),
    "mass_kg": ("road_load_mass_kg", ParamSpec(0.0, 100.0, 20000.0, "kg", "test mass of the coast-down "
                                                                        "(A scales with M / mass_kg)")),
}
ROAD_LOAD_CHECK_SPEED_M_S = 70.0  # the force must stay positive from 0 to 252 km/h
ROAD_LOAD_REPLACES = ("drag_area_m2", "rolling_resistance")  # the thesis terms a coast-down replaces
ROAD_LOAD_UNUSED = (*ROAD_LOAD_REPLACES, "air_density_kg_m3")  # what no model reads beside a coast-down


def road_load_minimum(a, b, c) -> tuple[np.ndarray, np.ndarray]:
    """Smallest A + B v + C v^2 over 0..ROAD_LOAD_CHECK_SPEED_M_S (N) and the speed where it is (m/s),
    per point (scalars or (N,) arrays): a coast-down must stay > 0 there (EPA's B can be negative)."""
    a, b, c = np.broadcast_arrays(*(np.atleast_1d(np.asarray(x, float)) for x in (a, b, c)))
    # C >= 0: the smallest value is at 0, at the top speed, or at the vertex -B / 2C between them
    vertex = np.divide(-b, 2.0 * c, out=np.zeros_like(b), where=c > 0)
    v = np.stack([np.zeros_like(a), np.full_like(a, ROAD_LOAD_CHECK_SPEED_M_S),
                  np.clip(vertex, 0.0, ROAD_LOAD_CHECK_SPEED_M_S)])
    f = a + b * v + c * v * v
    k = np.argmin(f, axis=0)
    cols = np.arange(a.shape[0])
    return f[k, cols], v[k, cols]

# chapter-5 analytic breakdown (breakdown.py)
BREAKDOWN_SPECS: dict[str, ParamSpec] = {
    **{k: VEHICLE_SPECS[k] for k in ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2",
                                     "rolling_resistance", "gear_efficiency", "regen_fraction")},
    "motor_efficiency": ParamSpec(0.85, 0.3, 1.0, "-", "average motor + inverter efficiency eta_m (ch.5: 85 %)"),
    "battery_voltage_v": ParamSpec(345.0, 10.0, 1500.0, "V", "constant battery voltage (ch.5: 345 V)"),
    "battery_discharge_resistance_ohm": ParamSpec(0.192, 0.0, 10.0, "ohm", "pack discharge resistance R_d (ch.5)"),
    "battery_charge_resistance_ohm": ParamSpec(0.216, 0.0, 10.0, "ohm", "pack charge resistance R_c (ch.5)"),
    "battery_loss_weight": ParamSpec(0.0, 0.0, 1.0, "-", "share of eq 5-19/5-20 battery losses in the total "
                                     "(0 = Table 5-1, which calls them negligible; 1 = eq 5-21)"),
}

# quasi-static map model (quasi_static.py) and the chapter-4 topologies built on it (topology.py)
QUASI_STATIC_SPECS: dict[str, ParamSpec] = {
    **{k: VEHICLE_SPECS[k] for k in ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2",
                                     "rolling_resistance", "wheel_radius_m", "gear_efficiency",
                                     "motor_torque_per_kw", "motor_speed_limit_rpm", "tyre_grip_coefficient",
                                     "driven_axle_load_share", "battery_to_shaft_efficiency")},
    "gear_count": ParamSpec(1.0, 1.0, 2.0, "-", "1 = single speed, 2 = two-speed gearbox (eq 2-6)",
                            integer=True),
    "gear_ratio_2": ParamSpec(4.7, 0.5, 50.0, "-", "second (high-speed) gear ratio (Table 3-2: 4.7)"),
    "shift_speed_m_s": ParamSpec(68.1 * KMH, 0.0, 100.0, "m/s", "two-speed shift point (Table 3-2: 68.1 km/h)"),
    "two_speed_efficiency_loss": ParamSpec(0.02, 0.0, 0.5, "-", "gear efficiency lost with two speeds (§3.3.2)"),
    "two_speed_added_mass_kg": ParamSpec(20.0, 0.0, 500.0, "kg", "mass added by two speeds (§3.7)"),
    "shift_strategy": ParamSpec(0.0, 0.0, 1.0, "-", "two-speed gear choice: 0 = shift speed rule (eq 2-6), "
                                "1 = per step the gear of least electrical power within the envelope",
                                integer=True),
    "regen_min_speed_m_s": ParamSpec(10.0 * KMH, 0.0, 50.0, "m/s", "no regeneration below this (§2.3.4: 10 km/h)"),
    "regen_max_decel_g": ParamSpec(0.7, 0.0, 5.0, "g", "friction only beyond this deceleration (§2.3.4)"),
    "regen_max_soc": ParamSpec(0.9, 0.0, 1.0, "-", "no regeneration above this SOC (§2.3.4)"),
    "charge_c_max": ParamSpec(bt.CHARGE_C_MAX, 0.0, 100.0, "1/h", "charge current limit in C (§2.3.4: 2C)"),
    "discharge_c_max": ParamSpec(bt.DISCHARGE_C_MAX, 0.0, 100.0, "1/h", "discharge current limit in C (§3.5.3: 5C)"),
    "cells_series": ParamSpec(float(bt.LEAF_CELLS_SERIES), 1.0, 1000.0, "-", "cells in series (Leaf: 96)"),
    "initial_soc": ParamSpec(0.9, 0.05, 1.0, "-", "SOC at the start of an energy run"),
    "final_soc": ParamSpec(0.05, 0.0, 0.9, "-", "range runs stop here (ch.3: 100 % -> 5 %)"),
    "battery_loss_weight": ParamSpec(0.0, 0.0, 1.0, "-", "0 = terminal energy (eq 2-17); 1 = adds the "
                                     "battery's internal I^2 R loss (energy at the open-circuit voltage)"),
    # topology constants (used by topology.py; Tables 4-1..4-3, §4.3.1)
    "dm_da_transmission_kg": ParamSpec(30.0, 0.0, 500.0, "kg", "DM-DA rear transmission mass (Table 4-1)"),
    "iwm_mass_factor": ParamSpec(0.75, 0.1, 1.0, "-", "in-wheel motor-unit mass factor, 25 % removed (Table 4-2)"),
    "iwm_torque_scale": ParamSpec(2.5, 0.1, 20.0, "-", "in-wheel map torque-axis factor (§4.3.1: 280 -> 700 Nm)"),
    "iwm_speed_scale": ParamSpec(210.0 / 1099.56, 0.01, 1.0, "-", "in-wheel map speed-axis factor "
                                 "(§4.3.1: max 1100 -> 210 rad/s; base speed 285.7 -> 54.6 rad/s, thesis 53)"),
    "torque_split_steps": ParamSpec(11.0, 3.0, 101.0, "-", "front/rear split grid size (odd: includes 50/50)",
                                    integer=True),
    # the motor written as its losses (loss_model.py) instead of the map; defaults: the default map's own
    # loss model (motor_map.py) with Fig 2-9's size scaling
    "motor_loss_model": ParamSpec(0.0, 0.0, 1.0, "-", "0 = efficiency map scaled by Fig 2-9 (the thesis), "
                                  "1 = the loss model of loss_model.py with the loss_* coefficients",
                                  integer=True),
    "loss_copper_w_per_nm2": ParamSpec(0.085, 0.0, 10.0, "W/(N*m)^2", "copper loss k_cu T^2 at the reference "
                                       "80 kW, x 80/P (eqs 6-21, 6-27)"),
    "loss_inverter_w_per_nm": ParamSpec(0.0, 0.0, 100.0, "W/(N*m)", "inverter conduction loss k_inv |T| "
                                        "(current ~ torque, eq 6-21)"),
    "loss_iron_w_s_per_rad": ParamSpec(2.5, 0.0, 100.0, "W*s/rad", "iron (hysteresis) loss k_fe w at 80 kW"),
    "loss_friction_w_s2_per_rad2": ParamSpec(1.6e-3, 0.0, 1.0, "W*s^2/rad^2", "friction and windage loss "
                                             "k_fr w^2 at 80 kW (eq 6-18: b w_m)"),
    "loss_constant_w": ParamSpec(300.0, 0.0, 10000.0, "W", "inverter switching/idle loss while turning, at 80 kW"),
    "loss_size_exponent": ParamSpec(1.0, 0.0, 2.0, "-", "iron, friction and constant losses x (P/80 kW)^e "
                                    "(1 = Fig 2-9's scaling)"),
    "driven_axles": ParamSpec(1.0, 1.0, 2.0, "-", "1, or 2: the rated power on two equal machines sharing the "
                              "torque (all-wheel drive of the single-motor model)", integer=True),
    "second_axle_drag_w": ParamSpec(0.0, 0.0, 5000.0, "W", "gear and bearing drag of a second driven axle "
                                    "while moving (driven_axles 2, or DM-DA)"),
    "excitation_loss_w_per_kw": ParamSpec(0.0, 0.0, 20.0, "W/kW", "rotor field excitation of wound-rotor "
                                          "synchronous machines (EESM) while turning, per kW of their rated power"),
    "wound_rotor_machine_share": ParamSpec(0.0, 0.0, 1.0, "-", "share of the rated power in wound-rotor "
                                           "synchronous machines (EESM), which excite their rotor field"),
    "regen_axle_share": ParamSpec(1.0, 0.0, 1.0, "-", "share of the braking force the motor(s) may take "
                                  "(the rest is friction braking; 1 = the thesis' rules only)"),
}

# wall-to-wheel chain (chain.py)
CHAIN_SPECS: dict[str, ParamSpec] = {
    **{k: VEHICLE_SPECS[k] for k in ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2", "rolling_resistance",
                                     "wheel_radius_m", "gear_efficiency", "motor_torque_per_kw")},
    "rotating_mass_fraction": ParamSpec(0.02, 0.0, 0.3, "-", "equivalent mass of rotating parts / vehicle mass"),
    "motor_loss_standby_fraction": ParamSpec(0.002, 0.0, 0.1, "-",
                                             "motor+inverter loss while moving at no load, / rated power (c_0)"),
    "motor_loss_speed_fraction": ParamSpec(0.0, 0.0, 0.1, "-",
                                           "speed-proportional motor+inverter loss at base speed, / rated power (c_w)"),
    "motor_loss_copper_fraction": ParamSpec(0.08, 0.0, 1.0, "-",
                                            "motor+inverter loss at peak torque, / rated power (c_cu, x tau^2)"),
    "regen_min_speed_m_s": QUASI_STATIC_SPECS["regen_min_speed_m_s"],
    "regen_max_power_kw": ParamSpec(150.0, 0.0, 1000.0, "kW", "regeneration power cap (battery charge limit)"),
    "regen_axle_share": ParamSpec(1.0, 0.0, 1.0, "-", "share of the braking force on the driven axle(s) "
                                  "(1 on a two-wheel dynamometer: the other axle stands still)"),
    **{k: BREAKDOWN_SPECS[k] for k in ("battery_voltage_v", "battery_discharge_resistance_ohm",
                                       "battery_charge_resistance_ohm")},
    "aux_power_w": ParamSpec(0.0, 0.0, 10000.0, "W", "auxiliary load while the cycle runs (12 V, cooling, HVAC)"),
    # technology: the car's machines and gearbox (fleet file columns) and what each costs
    **{k: QUASI_STATIC_SPECS[k] for k in ("gear_count", "two_speed_efficiency_loss", "driven_axles",
                                          "second_axle_drag_w")},
    "induction_machine_share": ParamSpec(0.0, 0.0, 1.0, "-", "share of the car's traction machines that are "
                                         "induction machines (0 = all synchronous)"),
    "induction_loss_fraction": ParamSpec(0.015, 0.0, 0.2, "-", "extra loss of an induction machine per unit of "
                                         "shaft power, rotor copper (§2.2.3: 1-2 % less efficient)"),
    "charger_efficiency": ParamSpec(1.0, 0.5, 1.0, "-", "wall-to-battery efficiency of a charge (1 = none)"),
}


# what only the chain reads (its loss terms, auxiliary load, regeneration cap): set on another energy model,
# refused (config.sections.validate_models), not ignored; the charger's efficiency gives every model's wall energy
CHAIN_ONLY = tuple(sorted(set(CHAIN_SPECS) - set(VEHICLE_SPECS) - set(BREAKDOWN_SPECS) - set(QUASI_STATIC_SPECS)
                          - {"charger_efficiency"}))


def all_specs() -> dict[str, ParamSpec]:
    """VEHICLE_SPECS plus the constants of the breakdown, quasi-static and chain models."""
    merged = dict(VEHICLE_SPECS)
    for specs in (BREAKDOWN_SPECS, QUASI_STATIC_SPECS, CHAIN_SPECS):
        merged.update({k: s for k, s in specs.items() if k not in merged})
    return merged


def validate_road_load(section: Any) -> dict[str, float]:
    """The ``vehicle.road_load`` mapping as the flat ``road_load_*`` parameters; one-line ValueError."""
    if not isinstance(section, Mapping):
        raise ValueError("road_load must be a mapping {a_n, b_n_per_m_s, c_n_per_m2_s2[, mass_kg]}")
    check_keys("vehicle.road_load", section, ROAD_LOAD_SPECS)
    if missing := [k for k in ("a_n", "b_n_per_m_s", "c_n_per_m2_s2") if k not in section]:
        raise ValueError(f"road_load: missing {missing} (all of a_n, b_n_per_m_s, c_n_per_m2_s2 are needed)")
    out = {"road_load_mass_kg": 0.0}
    for k, (flat_name, s) in ROAD_LOAD_SPECS.items():
        if k in section:
            out[flat_name] = check_value(f"road_load.{k}", section[k], s.lower, s.upper, s.unit)
    (low,), (at,) = road_load_minimum(out["road_load_a_n"], out["road_load_b_n_per_m_s"], out["road_load_c_n_per_m2_s2"])
    if low <= 0.0:
        raise ValueError(f"road_load: A + B v + C v^2 must stay > 0 up to {ROAD_LOAD_CHECK_SPEED_M_S:g} m/s; "
                         f"it is {low:.4g} N at {at:.3g} m/s")
    return out


_SPECS = all_specs()  # every model constant by name (get_params)

PARAMETER_SET_DIR = Path(__file__).resolve().parent.parent / "data" / "parameter_sets"


def parameter_set_names() -> list[str]:
    return sorted(p.stem for p in PARAMETER_SET_DIR.glob("*.yaml"))


def is_parameter_set_file(name: Any) -> bool:
    """Whether a parameter_set value names a file of the user's (a .yaml/.yml path), not a shipped set."""
    return isinstance(name, str) and Path(name).suffix.lower() in (".yaml", ".yml")


def load_parameter_set(name: str) -> dict[str, float]:
    """The ``parameters`` of a parameter set: a shipped one by name (bev_mdo/data/parameter_sets/<name>.yaml), or a
    file of yours by its .yaml/.yml path (relative: to the config's folder, config.sections.anchor_paths)."""
    return _read_parameter_set(name)[0]


def fitted_values(name: str) -> dict[str, float]:
    """The parameters set ``name`` fitted (its ``fit``), with the values it applies. ValueError as above."""
    fit = _set_document(name)[1].get("fit")
    return {k: v for k, v in load_parameter_set(name).items() if isinstance(fit, dict) and k in fit}


# the energy models of a config (``energy_model``); a parameter set names one of them, or ANY_MODEL
ENERGY_MODELS = ("flat", "breakdown", "quasi_static", "chain")
ANY_MODEL = "any"


def fitted_for_another_model(name: str, energy_model: str) -> str | None:
    """The energy model a parameter set was fitted for (its ``energy_model``; ``bev-mdo calibrate`` writes
    it) when that is not ``energy_model``, else None; a set for ``any`` model (constants that mean the same
    in each) fits every one. ``topology_sm_sa`` (bev-mdo validate) is the quasi-static model."""
    fitted = _read_parameter_set(name)[1]
    runs = {"topology_sm_sa": "quasi_static"}.get(energy_model, energy_model)
    return fitted if fitted not in (ANY_MODEL, runs) else None


def _set_model(doc: dict, path: Path, own: bool) -> str:
    """The energy model a set is for. A file of the user's must say (a chain set used on the quasi-static
    model put it 77 % over the fleet without a word): a model's name, or ``any``. A shipped set without
    one (the thesis' constants, the models' own defaults) is for any model."""
    model = doc.get("energy_model")
    if model is None and not own:
        return ANY_MODEL
    if model is None:
        raise ValueError(f"{path}: no 'energy_model': name the model its values are for "
                         f"({', '.join(ENERGY_MODELS)}), or '{ANY_MODEL}' if they mean the same in every model")
    if model not in (*ENERGY_MODELS, ANY_MODEL):
        raise ValueError(f"{path}: energy_model {model!r} is unknown; allowed: {', '.join(ENERGY_MODELS)}, {ANY_MODEL}")
    return model


# the top-level keys of a parameter set (what ``bev-mdo calibrate`` writes; only 'parameters' is applied)
PARAMETER_SET_KEYS = ("name", "energy_model", "description", "fitted_on", "fit", "fixed_not_fitted", "quality",
                      "parameters")


def _check_fit(doc: dict) -> None:
    """Refused, not applied: a fitted value whose standard error is not a number (the data did not determine it), and
    ``parameters`` that lack or differ from what the set's ``fit`` and ``fixed_not_fitted`` say (a set cut short or
    edited ran 17 % off the fleet, still called the fit's: its quality figures are not its own)."""
    fit, values = doc.get("fit") if isinstance(doc.get("fit"), dict) else {}, doc["parameters"]
    for k, entry in fit.items():
        se, value = (entry.get("std_error"), entry.get("value")) if isinstance(entry, dict) else (None, None)
        if se is not None and not (isinstance(se, (int, float)) and math.isfinite(se)):
            raise ValueError(f"fit.{k}: std_error {se!r}: the data did not determine this value; refit with "
                             "bev-mdo calibrate (it writes the model's default there) or set it yourself")
        if k not in values or is_number(value) and is_number(values[k]) and not math.isclose(  # (6 decimals written)
                values[k], value, rel_tol=1e-5, abs_tol=1e-6):
            raise ValueError(f"parameters.{k}: {values.get(k, 'missing')}, but fit.{k} is {value}: a set edited or cut "
                             "after its fit; refit, or drop fit, fixed_not_fitted and quality to make it your own")
    if (missing := [str(k) for k in doc.get("fixed_not_fitted") or () if k not in values]):
        raise ValueError(f"parameters: {', '.join(missing)} missing, which fixed_not_fitted lists: a set cut after its "
                         "fit; refit, or drop fit, fixed_not_fitted and quality to make it your own")


# what a run records of a set given as a file (vehicle.parameter_set_source): its values are in the config
SOURCE_KEYS = ("name", "file", "sha256", "fitted")


def parameter_set_source(name: str) -> dict[str, str]:
    """Which set ``name`` is: its ``name``, for a file its absolute ``file`` and ``sha256``, and ``fitted``
    (the date its fit ran, from its ``fitted_on``) where it says; ``fitted_on``: the fleet it was fitted on,
    as the set records it ({} when it does not); ``notes``: its ``quality.notes`` (what calibrate noted of the
    fit: a fleet in other units, a parameter at a bound). ValueError as :func:`load_parameter_set`."""
    import hashlib

    path, doc = _set_document(name)
    fitted_on = doc.get("fitted_on") if isinstance(doc.get("fitted_on"), dict) else {}
    out = {"name": str(doc.get("name") or path.stem)}
    if is_parameter_set_file(name):
        out.update(file=str(path.resolve()), sha256=hashlib.sha256(path.read_bytes()).hexdigest())
    if fitted_on.get("date"):
        out["fitted"] = str(fitted_on["date"])
    notes = doc["quality"].get("notes") if isinstance(doc.get("quality"), dict) else None
    return {**out, "fitted_on": {str(k): v for k, v in fitted_on.items()},
            "notes": [str(n) for n in notes] if isinstance(notes, list) else []}


def _set_document(name: str) -> tuple[Path, dict]:
    """The file of set ``name`` and its YAML mapping, read and checked as :func:`_read_parameter_set` says."""
    from bev_mdo.yamlload import read_yaml_file

    if not isinstance(name, str) or not name or not is_parameter_set_file(name) and ("/" in name or name[0] == "."):
        raise ValueError(f"parameter_set must be one of {parameter_set_names()} or a .yaml path, got {name!r}")
    if is_parameter_set_file(name):
        path = Path(name).expanduser()
        if not path.is_file():
            raise ValueError(f"parameter_set {name!r}: no such file")
    elif not (path := PARAMETER_SET_DIR / f"{name}.yaml").is_file():
        raise ValueError(f"parameter_set {name!r} is unknown; shipped: {parameter_set_names()} (or give a .yaml path)")
    doc = read_yaml_file(path)  # one-line errors naming the file; a key given twice is refused, not the last kept
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: not a YAML parameter set (a mapping with 'parameters')")
    try:  # a misspelt section or parameter would otherwise do nothing, silently
        check_keys("", doc, PARAMETER_SET_KEYS)
        if not isinstance(values := doc.get("parameters"), dict):
            raise ValueError("no 'parameters' mapping")
        check_keys("parameters", values, all_specs())
        _check_fit(doc)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return path, doc


def _read_parameter_set(name: str) -> tuple[dict[str, float], str]:
    """(the set's parameters, the energy model it is for: ``_set_model``)."""
    path, doc = _set_document(name)
    values, specs = doc["parameters"], all_specs()
    out = {}
    for k, v in values.items():  # each in its range, as a config's vehicle section (validate took 0.1 and 1.9)
        s = specs[k]
        try:
            out[str(k)] = check_value(str(k), v, s.lower, s.upper, s.unit, s.integer)
        except ValueError as exc:
            raise ValueError(f"{path}: parameters.{exc}") from None
    return out, _set_model(doc, path, is_parameter_set_file(name))


def topology_name(name: Any) -> str:
    """The canonical topology name (SM-SA, DM-DA, IWM-SA, IWM-DA) of ``name`` in any case; one-line ValueError."""
    allowed = VEHICLE_CHOICES["topology"]
    if not isinstance(name, str) or name.upper() not in allowed:
        raise ValueError(f"topology must be one of {', '.join(allowed)}, got {name!r}")
    return name.upper()


GEAR_ORDER = "with gear_count 2 the second gear must not be shorter than the first (gear_ratio_2 <= gear_ratio)"


def gears_out_of_order(gear_count, gear_ratio, gear_ratio_2) -> np.ndarray:
    """True where a two-speed box (``gear_count`` 2) has its second, high-speed gear shorter than the first:
    ``gear_ratio_2`` above ``gear_ratio`` (Table 3-2: 4.7 below the first). Numbers or arrays, broadcast."""
    return (np.asarray(gear_count, float) >= 2) & (np.asarray(gear_ratio_2, float) > np.asarray(gear_ratio, float))


def validate_vehicle(section: Mapping[str, Any] | None) -> dict[str, float]:
    """Fill defaults, reject unknown names, range-check every numeric vehicle parameter.

    Choice keys (``mass_model``, ``topology``) are checked but not returned; read them with
    :func:`vehicle_choice`."""
    section = dict(section or {})
    specs = all_specs()
    road = section.pop("road_load", None)
    flat_road = {k: section.pop(k) for k in list(section) if k.startswith("road_load_")}
    if flat_road:  # the resolved form a discipline node receives (see road_load.FLAT_KEYS)
        if road is not None:
            raise ValueError("give road_load or its road_load_* parameters, not both")
        names = {flat: key for key, (flat, _) in ROAD_LOAD_SPECS.items()}
        check_keys("vehicle", flat_road, names)
        road = {names[k]: v for k, v in flat_road.items() if not (k == "road_load_mass_kg" and v == 0)}
    chain = section.pop("parameter_set", None)
    source = section.pop("parameter_set_source", None)  # which file set's values the section holds (a run's record)
    if source is not None and not (isinstance(source, Mapping) and all(isinstance(v, str) for v in source.values())):
        raise ValueError(f"vehicle.parameter_set_source must be a mapping of {', '.join(SOURCE_KEYS)} to text")
    check_keys("vehicle.parameter_set_source", source or {}, SOURCE_KEYS)
    check_keys("vehicle", section, [*specs, *VEHICLE_CHOICES, "parameter_set", "parameter_set_source", "road_load"])
    for k in VEHICLE_CHOICES:
        vehicle_choice(section, k)
    # a calibration: its values are defaults the section may override
    extra = {} if chain is None else {k: v for k, v in load_parameter_set(chain).items() if k not in section}
    out = {k: check_value(k, section.get(k, extra.get(k, s.default)), s.lower, s.upper, s.unit, s.integer)
           for k, s in specs.items()}
    topology = vehicle_choice(section, "topology")
    check_sm_sa_only(topology, out, "vehicle.")
    if road is not None:
        both = sorted(k for k in ROAD_LOAD_REPLACES if k in section)
        if both and not flat_road:  # the resolved form carries every parameter, defaults included
            raise ValueError(f"road_load replaces {both}: give one or the other")
        out.update(validate_road_load(road))
    return out


def vehicle_choice(section: Mapping[str, Any] | None, key: str) -> str:
    """A validated choice value from the vehicle section (first allowed value by default)."""
    allowed = VEHICLE_CHOICES[key]
    value = (section or {}).get(key, allowed[0])
    if key == "topology":
        return topology_name(value)  # one line naming SM-SA, DM-DA, IWM-SA, IWM-DA
    if value not in allowed:
        raise ValueError(f"vehicle {key} must be one of {list(allowed)}, got {value!r}")
    return str(value)


def validate_cycle(section: Mapping[str, Any] | None) -> dict:
    """Validate the ``cycle`` section: name, dt_s, interpolation (linear|pchip|spline), smoothing."""
    section = dict(section or {})
    known = {"name", "dt_s", "interpolation", "smoothing"}
    check_keys("cycle", section, known)
    name = section.get("name", "nedc")
    if not isinstance(name, str) or not name:
        raise ValueError(f"cycle name must be a cycle name or CSV path, got {name!r}")
    s = CYCLE_SPECS["dt_s"]
    dt = check_value("cycle dt_s", section.get("dt_s", s.default), s.lower, s.upper, s.unit)
    method = section.get("interpolation", DEFAULT_METHOD)
    if method not in METHODS:
        raise ValueError(f"cycle interpolation must be one of {list(METHODS)}, got {method!r}")
    smoothing = None if section.get("smoothing") is None else check_value("cycle smoothing", section["smoothing"],
                                                                            0.0, 1e12)
    return {"name": name, "dt_s": dt, "interpolation": method, "smoothing": smoothing}


def get_params(params: Mapping[str, Any] | None, names: tuple[str, ...]) -> dict:
    """Values for ``names`` from ``params`` (defaults filled), each a float or an array, range-checked."""
    params = params or {}
    out = {}
    for k in names:
        s = _SPECS[k]
        v = params.get(k, s.default)
        if type(v) is float and s.lower <= v <= s.upper and (not s.integer or v == round(v)):
            out[k] = v
            continue
        a = check_array(k, v, s.lower, s.upper, s.unit)
        if s.integer and np.any(a != np.round(a)):  # a count or a switch
            bad = a[a != np.round(a)].flat[0]
            raise ValueError(f"{k} must be {allowed(s.lower, s.upper, s.unit, True)}, got {bad:g}")
        out[k] = float(a) if a.ndim == 0 else a
    return out
