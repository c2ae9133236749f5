"""Quantities and units from bev_mdo's variable names (the unit is in the name: ``energy_wh_per_km``).

``label("energy_wh_per_km")`` -> ``"energy (Wh/km)"`` for plot axes and tables;
``unit_of("range_km")`` -> ``"km"``. Unknown suffixes give the name itself and no unit.
"""
from __future__ import annotations

# suffix -> unit, longest first
_SUFFIXES = (
    ("_wh_per_km", "Wh/km"), ("_kwh_per_100km", "kWh/100 km"), ("_rad_s", "rad/s"), ("_m_s2", "m/s²"),
    ("_kg_m3", "kg/m³"), ("_nm_a", "N·m/A"), ("_kwh", "kWh"), ("_kmh", "km/h"), ("_usd", "US$"),
    ("_ohm", "Ω"), ("_rpm", "rpm"), ("_kw", "kW"), ("_kg", "kg"), ("_km", "km"), ("_m2", "m²"), ("_nm", "N·m"),
    ("_m", "m"), ("_h", "H"), ("_s", "s"), ("_pct", "%"),
)

# nicer quantity names for the built-in variables
_QUANTITY = {
    "energy_wh_per_km": "energy consumption",
    "range_km": "range",
    "accel_time_0_100_s": "0–100 km/h time",
    "motor_speed_max_rad_s": "max motor speed",
    "powertrain_cost_usd": "powertrain cost",
    "vehicle_mass_kg": "vehicle mass",
    "motor_kw": "motor power",
    "motor_rear_kw": "rear motor power",
    "battery_kwh": "battery capacity",
    "gear_ratio": "gear ratio",
    "gear_ratio_rear": "rear gear ratio",
    "top_speed_kmh": "top speed",
    "max_violation": "max constraint violation",
}

_UNITLESS = {"gear_ratio": "–", "gear_ratio_rear": "–"}


def split(name: str) -> tuple[str, str]:
    """(quantity, unit) of a variable name."""
    if name in _UNITLESS:
        return _QUANTITY.get(name, name), ""
    for suf, unit in _SUFFIXES:
        if name.endswith(suf) and len(name) > len(suf):
            return _QUANTITY.get(name, name[: -len(suf)].replace("_", " ")), unit
    return _QUANTITY.get(name, name.replace("_", " ")), ""


def unit_of(name: str) -> str:
    return split(name)[1]


def label(name: str) -> str:
    """Axis label: quantity and unit, e.g. ``energy consumption (Wh/km)``; ``gear ratio (–)``."""
    q, u = split(name)
    if name in _UNITLESS:
        return f"{q} (–)"
    return f"{q} ({u})" if u else q
