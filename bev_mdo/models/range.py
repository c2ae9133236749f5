"""Driving range from battery capacity and energy per km (eq 7-28) and its inverse."""
from __future__ import annotations

from .common import check_array, check_design, check_lengths
from .params import VEHICLE_SPECS

_U = VEHICLE_SPECS["battery_usable_fraction"]


def range_km(battery_kwh, energy_wh_per_km, usable_fraction=_U.default):
    """Eq 7-28: range = usable x battery_kWh x 1000 / E_Wh_per_km (usable = 1 in the thesis)."""
    f = check_array("battery_usable_fraction", usable_fraction, _U.lower, _U.upper)
    b, e = check_design("battery_kwh", battery_kwh), check_design("energy_wh_per_km", energy_wh_per_km)
    check_lengths(battery_kwh=b, energy_wh_per_km=e, battery_usable_fraction=f)
    return f * b * 1000.0 / e


def battery_kwh_for_range(range_target_km, energy_wh_per_km, usable_fraction=_U.default):
    """Eq 7-28 solved for the battery: kWh = range x E_Wh_per_km / (1000 x usable)."""
    f = check_array("battery_usable_fraction", usable_fraction, _U.lower, _U.upper)
    r, e = check_design("range_target_km", range_target_km), check_design("energy_wh_per_km", energy_wh_per_km)
    check_lengths(range_target_km=r, energy_wh_per_km=e, battery_usable_fraction=f)
    return r * e / (1000.0 * f)
