"""Vehicle mass from motor power and battery capacity (eqs 7-19..7-21, ch.3 compounding)."""
from __future__ import annotations

from .common import check_array, check_design, check_lengths
from .params import VEHICLE_SPECS

DEFAULTS = {k: s.default for k, s in VEHICLE_SPECS.items()}  # the defaults of every vehicle parameter


def _checked(**params):
    """The mass parameters given by name, each within its physical range of VEHICLE_SPECS (finite, e.g.
    glider_kg in [200, 5000] kg): a one-line ValueError naming the parameter and its unit otherwise."""
    for name, value in params.items():
        spec = VEHICLE_SPECS[name]
        if type(value) is float:  # the usual: a configured constant
            if not spec.lower <= value <= spec.upper:  # also false for nan
                check_array(name, value, spec.lower, spec.upper, spec.unit)
        else:
            check_array(name, value, spec.lower, spec.upper, spec.unit)


def motor_mass_kg(motor_kw, kg_per_kw=DEFAULTS["motor_kg_per_kw"], base_kg=DEFAULTS["motor_base_kg"]):
    """Eq 7-20 / 2-18: M_m = 0.532 P_kW + 21.6."""
    kw = check_design("motor_kw", motor_kw)
    _checked(motor_kg_per_kw=kg_per_kw, motor_base_kg=base_kg)
    check_lengths(motor_kw=kw, motor_kg_per_kw=kg_per_kw, motor_base_kg=base_kg)
    return kg_per_kw * kw + base_kg


def battery_mass_kg(battery_kwh, kg_per_kwh=DEFAULTS["battery_kg_per_kwh"]):
    """Eq 7-21: M_b = 7.8 E_kWh."""
    kwh = check_design("battery_kwh", battery_kwh)
    _checked(battery_kg_per_kwh=kg_per_kwh)
    check_lengths(battery_kwh=kwh, battery_kg_per_kwh=kg_per_kwh)
    return kg_per_kwh * kwh


def vehicle_mass_ch7_kg(motor_kw, battery_kwh, glider_kg=DEFAULTS["glider_kg"], load_kg=DEFAULTS["load_kg"],
                        motor_kg_per_kw=DEFAULTS["motor_kg_per_kw"], motor_base_kg=DEFAULTS["motor_base_kg"],
                        battery_kg_per_kwh=DEFAULTS["battery_kg_per_kwh"]):
    """Eq 7-19: M_v = M_B + M_m + M_b + M_L."""
    kw, kwh = check_design("motor_kw", motor_kw), check_design("battery_kwh", battery_kwh)
    _checked(glider_kg=glider_kg, load_kg=load_kg, motor_kg_per_kw=motor_kg_per_kw, motor_base_kg=motor_base_kg,
             battery_kg_per_kwh=battery_kg_per_kwh)
    check_lengths(motor_kw=kw, battery_kwh=kwh, glider_kg=glider_kg, load_kg=load_kg, motor_kg_per_kw=motor_kg_per_kw,
                  motor_base_kg=motor_base_kg, battery_kg_per_kwh=battery_kg_per_kwh)
    return glider_kg + load_kg + (motor_kg_per_kw * kw + motor_base_kg) + battery_kg_per_kwh * kwh  # 7-20, 7-21


def kerb_mass_compounding_kg(motor_kw, battery_kwh, kerb_reference_kg=DEFAULTS["kerb_reference_kg"],
                             reference_motor_kw=DEFAULTS["reference_motor_kw"],
                             reference_battery_kwh=DEFAULTS["reference_battery_kwh"],
                             mass_compounding=DEFAULTS["mass_compounding"],
                             motor_kg_per_kw=DEFAULTS["motor_kg_per_kw"], motor_base_kg=DEFAULTS["motor_base_kg"],
                             battery_kg_per_kwh=DEFAULTS["battery_kg_per_kwh"]):
    """Ch.3 rule: kerb = 1521 kg + 1.6 x (powertrain mass - powertrain mass at 80 kW / 24 kWh).

    The powertrain mass is eq 2-18 + 2-20 (battery by eq 7-21). Note: Table 3-1's 1689 kg
    multiplies the whole new powertrain by 1.6, not the difference (docs/thesis.md, the compounding rule)."""
    kw, kwh = check_design("motor_kw", motor_kw), check_design("battery_kwh", battery_kwh)
    _checked(kerb_reference_kg=kerb_reference_kg, reference_motor_kw=reference_motor_kw,
             reference_battery_kwh=reference_battery_kwh, mass_compounding=mass_compounding,
             motor_kg_per_kw=motor_kg_per_kw, motor_base_kg=motor_base_kg, battery_kg_per_kwh=battery_kg_per_kwh)
    check_lengths(motor_kw=kw, battery_kwh=kwh, kerb_reference_kg=kerb_reference_kg, reference_motor_kw=reference_motor_kw,
                  reference_battery_kwh=reference_battery_kwh, mass_compounding=mass_compounding,
                  motor_kg_per_kw=motor_kg_per_kw, motor_base_kg=motor_base_kg, battery_kg_per_kwh=battery_kg_per_kwh)
    pt = (motor_kg_per_kw * kw + motor_base_kg) + battery_kg_per_kwh * kwh  # 2-18, 7-21
    pt_ref = (motor_kg_per_kw * reference_motor_kw + motor_base_kg) + battery_kg_per_kwh * reference_battery_kwh
    return kerb_reference_kg + mass_compounding * (pt - pt_ref)


def vehicle_mass_kg(motor_kw, battery_kwh, params: dict, mass_model: str = "ch7"):
    """Vehicle mass for the energy and acceleration models: ch7 (eq 7-19) or ch.3 compounding
    kerb mass plus ``load_kg``. ``params`` holds VEHICLE_SPECS names (scalars or (N,) arrays)."""
    p = {**DEFAULTS, **params}
    common = dict(motor_kg_per_kw=p["motor_kg_per_kw"], motor_base_kg=p["motor_base_kg"],
                  battery_kg_per_kwh=p["battery_kg_per_kwh"])
    if mass_model == "ch7":
        return vehicle_mass_ch7_kg(motor_kw, battery_kwh, p["glider_kg"], p["load_kg"], **common)
    if mass_model == "compounding":
        return p["load_kg"] + kerb_mass_compounding_kg(
            motor_kw, battery_kwh, p["kerb_reference_kg"], p["reference_motor_kw"],
            p["reference_battery_kwh"], p["mass_compounding"], **common)
    raise ValueError(f"mass_model must be one of ['ch7', 'compounding'], got {mass_model!r}")
