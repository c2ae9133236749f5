"""Model constants with units, defaults and physical ranges; validation of config sections."""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np


@dataclass(frozen=True)
class ParamSpec:
    """One model constant: default value, allowed closed range [lower, upper], unit, meaning."""

    default: float
    lower: float
    upper: float
    unit: str
    description: str


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
    "load_kg": ParamSpec(69.0, 0.0, 1000.0, "kg", "load and rotational-inertia mass M_L (eq 7-19)"),
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
}

# topology (thesis ch.4): one setting for every topology discipline (vehicle_mass, energy,
# cycle_range, acceleration, cost); any case, e.g. iwm-sa (models.topology.get_topology)
VEHICLE_CHOICES: dict[str, tuple[str, ...]] = {"mass_model": ("ch7", "compounding"),
                                               "topology": ("SM-SA", "DM-DA", "IWM-SA", "IWM-DA")}

CYCLE_SPECS: dict[str, ParamSpec] = {
    "dt_s": ParamSpec(1.0, 0.01, 10.0, "s", "resampling step"),
}


def _merge_specs(base: dict[str, ParamSpec]) -> dict[str, ParamSpec]:
    merged = dict(base)
    for mod in ("bev_mdo.models.breakdown", "bev_mdo.models.quasi_static", "bev_mdo.models.chain"):
        try:
            specs = getattr(importlib.import_module(mod), "PARAM_SPECS", {})
        except ImportError:
            continue
        for k, s in specs.items():
            merged.setdefault(k, s)
    return merged


def all_specs() -> dict[str, ParamSpec]:
    """VEHICLE_SPECS plus PARAM_SPECS of the breakdown, quasi-static and chain models, if present."""
    return _merge_specs(VEHICLE_SPECS)


def check_value(name: str, value: Any, lower: float, upper: float, unit: str = "") -> float:
    """Return ``value`` as float; ValueError naming ``name`` and [lower, upper] otherwise."""
    u = f" {unit}" if unit and unit != "-" else ""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number in [{lower:g}, {upper:g}]{u}, got {value!r}") from None
    if not (math.isfinite(x) and lower <= x <= upper):
        raise ValueError(f"{name} must be in [{lower:g}, {upper:g}]{u}, got {x:g}")
    return x


def check_array(name: str, values: Any, lower: float, upper: float, unit: str = "") -> np.ndarray:
    """Vector form of :func:`check_value`: names the first bad element."""
    a = np.asarray(values, dtype=float)
    if a.size == 1:  # one design point (an MDA over ROS, a line search): ~0.3 µs instead of ~4.5
        x = a.item()
        if math.isfinite(x) and lower <= x <= upper:
            return a
    bad = ~(np.isfinite(a) & (a >= lower) & (a <= upper))
    if bad.any():
        u = f" {unit}" if unit and unit != "-" else ""
        first = a.reshape(-1)[np.flatnonzero(bad.reshape(-1))[0]]
        raise ValueError(f"{name} must be in [{lower:g}, {upper:g}]{u}, got {first:g}")
    return a


def check_param(name: str, value: Any) -> np.ndarray | float:
    """Check a known parameter (scalar or array) against its spec."""
    s = all_specs()[name]
    if np.ndim(value):
        return check_array(name, value, s.lower, s.upper, s.unit)
    return check_value(name, value, s.lower, s.upper, s.unit)


def validate_vehicle(section: Mapping[str, Any] | None) -> dict[str, float]:
    """Fill defaults, reject unknown names, range-check every numeric vehicle parameter.

    Choice keys (``mass_model``, ``topology``) are checked but not returned; read them with
    :func:`vehicle_choice`."""
    section = dict(section or {})
    specs = all_specs()
    road = section.pop("road_load", None)
    flat_road = {k: section.pop(k) for k in list(section) if k.startswith("road_load_")}
    if flat_road:  # the resolved form a discipline node receives (see road_load.FLAT_KEYS)
        from .road_load import ROAD_LOAD_SPECS

        if road is not None:
            raise ValueError("give road_load or its road_load_* parameters, not both")
        names = {flat: key for key, (flat, _) in ROAD_LOAD_SPECS.items()}
        unknown = sorted(k for k in flat_road if k not in names)
        if unknown:
            raise ValueError(f"unknown vehicle parameter(s) {unknown}")
        road = {names[k]: v for k, v in flat_road.items() if not (k == "road_load_mass_kg" and v == 0)}
    chain = section.pop("parameter_set", None)
    unknown = sorted(k for k in section if k not in specs and k not in VEHICLE_CHOICES)
    if unknown:
        raise ValueError(f"unknown vehicle parameter(s) {unknown}; known: "
                         f"{sorted(specs) + sorted(VEHICLE_CHOICES) + ['parameter_set', 'road_load']}")
    for k in VEHICLE_CHOICES:
        vehicle_choice(section, k)
    extra: dict[str, float] = {}
    if chain is not None:  # a shipped calibration: its values are defaults the section may override
        from .chain import load_parameter_set

        extra = {k: v for k, v in load_parameter_set(chain).items() if k not in section}
    out = {k: check_value(k, section.get(k, extra.get(k, s.default)), s.lower, s.upper, s.unit)
           for k, s in specs.items()}
    if road is not None:
        from .road_load import validate_road_load

        both = sorted(k for k in ("drag_area_m2", "rolling_resistance") if k in section)
        if both and not flat_road:  # the resolved form carries every parameter, defaults included
            raise ValueError(f"road_load replaces {both}: give one or the other")
        out.update(validate_road_load(road))
    return out


def vehicle_choice(section: Mapping[str, Any] | None, key: str) -> str:
    """A validated choice value from the vehicle section (first allowed value by default)."""
    allowed = VEHICLE_CHOICES[key]
    value = (section or {}).get(key, allowed[0])
    if key == "topology":
        from .topology import get_topology

        return get_topology(value).name  # one line naming SM-SA, DM-DA, IWM-SA, IWM-DA
    if value not in allowed:
        raise ValueError(f"vehicle {key} must be one of {list(allowed)}, got {value!r}")
    return str(value)


def validate_cycle(section: Mapping[str, Any] | None) -> dict:
    """Validate the ``cycle`` section: name, dt_s, interpolation (linear|pchip|spline), smoothing."""
    from .cycles import DEFAULT_METHOD, METHODS

    section = dict(section or {})
    known = {"name", "dt_s", "interpolation", "smoothing"}
    unknown = sorted(set(section) - known)
    if unknown:
        raise ValueError(f"unknown cycle key(s) {unknown}; known: {sorted(known)}")
    name = section.get("name", "nedc")
    if not isinstance(name, str) or not name:
        raise ValueError(f"cycle name must be a cycle name or CSV path, got {name!r}")
    s = CYCLE_SPECS["dt_s"]
    dt = check_value("cycle dt_s", section.get("dt_s", s.default), s.lower, s.upper, s.unit)
    method = section.get("interpolation", DEFAULT_METHOD)
    if method not in METHODS:
        raise ValueError(f"cycle interpolation must be one of {list(METHODS)}, got {method!r}")
    smoothing = section.get("smoothing")
    if smoothing is not None:
        smoothing = check_value("cycle smoothing", smoothing, 0.0, 1e12)
    return {"name": name, "dt_s": dt, "interpolation": method, "smoothing": smoothing}


def validate_design(name: str, values: Any, lower: float, upper: float) -> np.ndarray:
    """Design-variable array check: finite and within [lower, upper], ValueError naming it."""
    return check_array(name, np.atleast_1d(values), lower, upper)


# Physical ranges for design variables and coupling variables the models accept.
DESIGN_LIMITS: dict[str, tuple[float, float]] = {
    "motor_kw": (1.0, 1000.0),
    "gear_ratio": (0.5, 50.0),
    "battery_kwh": (1.0, 500.0),
    "vehicle_mass_kg": (100.0, 20000.0),
    "energy_wh_per_km": (1.0, 5000.0),
    "range_target_km": (1.0, 10000.0),
}


def check_design(name: str, values: Any) -> np.ndarray:
    """Check a design or coupling variable against :data:`DESIGN_LIMITS`."""
    lo, hi = DESIGN_LIMITS[name]
    return validate_design(name, values, lo, hi)


def get_params(params: Mapping[str, Any] | None, names: tuple[str, ...]) -> dict:
    """Values for ``names`` from ``params`` (defaults filled), each a float or an array, range-checked."""
    params = params or {}
    out = {}
    for k in names:
        s = VEHICLE_SPECS[k]
        v = params.get(k, s.default)
        if type(v) is float and s.lower <= v <= s.upper:
            out[k] = v
            continue
        a = check_array(k, v, s.lower, s.upper, s.unit)
        out[k] = float(a) if a.ndim == 0 else a
    return out
