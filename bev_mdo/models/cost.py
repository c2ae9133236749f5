"""Powertrain cost in US$ (eqs 2-21..2-24, long-term assumptions of the thesis' ref. [46])."""
from __future__ import annotations

import numpy as np

from .common import check_array, check_design, check_lengths
from .params import VEHICLE_SPECS

_PE = VEHICLE_SPECS["power_to_energy_ratio"]


def motor_cost_usd(motor_kw):
    """Eq 2-21: 16 P_kW + 385."""
    return 16.0 * check_design("motor_kw", motor_kw) + 385.0


def cell_cost_usd_per_kwh(power_to_energy_ratio=_PE.default):
    """Eq 2-22: 11.1 (P/E) + 221.1 (P/E = 4 for the lithium cell assumed in the thesis)."""
    return 11.1 * check_array("power_to_energy_ratio", power_to_energy_ratio, _PE.lower, _PE.upper) + 221.1


def pack_cost_usd(battery_kwh, power_to_energy_ratio=_PE.default):
    """Eq 2-23: (cell $/kWh + 13) E_kWh + 680."""
    cell, kwh = cell_cost_usd_per_kwh(power_to_energy_ratio), check_design("battery_kwh", battery_kwh)
    check_lengths(battery_kwh=kwh, power_to_energy_ratio=cell)
    return (cell + 13.0) * kwh + 680.0


def powertrain_cost_usd(motor_kw, battery_kwh, power_to_energy_ratio=_PE.default):
    """Eq 2-24: motor + pack."""
    motor, pack = motor_cost_usd(motor_kw), pack_cost_usd(battery_kwh, power_to_energy_ratio)
    if motor.shape != pack.shape:  # one of them (1,), or a message naming the inputs instead of numpy's
        check_lengths(motor_kw=np.atleast_1d(motor_kw), battery_kwh=np.atleast_1d(battery_kwh),
                      power_to_energy_ratio=power_to_energy_ratio)
    return motor + pack
