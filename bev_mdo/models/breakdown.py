"""Chapter-5 analytic energy breakdown (thesis eqs 5-12..5-21, Table 5-1).

The cycle is taken as linear between samples. On each step [t_i, t_i+1] the thesis uses
the mean speed v_bar (eq 5-12) and the step's acceleration a = dv/dt, and sums over the
steps (the 1 Hz sums of eqs 5-13..5-15):

* aerodynamic   E_aero    = 1/2 rho C_dA sum(v_bar^3 dt) / x_total          (5-13)
* rolling       E_roll    = g M C_r sum(v_bar dt) / x_total = g M C_r        (5-14)
* inertia       E_inertia = M sum(max(a, 0) v_bar dt) / x_total              (5-15)
  (= the sum of the kinetic-energy rises over the cycle)
* regeneration  E_regen   = r E_inertia                                      (5-16)
* gear loss     (E_aero + E_roll + E_inertia + E_regen)(1 - eta_g)           (5-17)
* motor loss    (E_aero + E_roll + E_inertia + E_regen + E_gear)(1 - eta_m)  (5-18)
  (both count the regenerated energy flowing back through gear and motor: this is
  what reproduces Table 5-1's loss rows, e.g. 0.42 / 2.16 at 40 %)
* battery       (E_dis / (T V))^2 R_d T and (E_regen / (T V))^2 R_c T       (5-19, 5-20)
  with E_dis the traction energy drawn (aero + rolling + inertia + gear + motor)
* total         aero + roll + inertia - regen + gear + motor
                + w (battery discharge + charge)                             (5-21)

Battery losses: eqs 5-19/5-20 in SI give ~0.11 kWh/100 km on the NEDC (0.8 % of the
total), yet Table 5-1 lists them as "Negligible" and its totals are exactly the sums of
the other rows. ``battery_loss_weight`` w chooses: 0 (default) = Table 5-1 as published,
1 = eq 5-21 as printed. The battery rows are always reported.

With x_total = sum(v_bar dt) (trapezoid distance), M = 1590 kg, C_dA = 0.6412 m^2,
C_r = 0.007, eta_g = 0.97, eta_m = 0.85 this gives Table 5-1's NEDC column within
0.7 % per row. Every term is a polynomial in the parameters (no switches, no abs), so
the model is smooth and accepts complex parameters for complex-step derivatives.
"""
from __future__ import annotations

import numpy as np

from . import road_load as rl
from .common import batch_size, design_points, resolve_params
from .params import BREAKDOWN_SPECS

J_PER_M_TO_KWH_PER_100KM = 1e5 / 3.6e6  # 1 J/m = 1/36 kWh/100 km

PARAM_SPECS = BREAKDOWN_SPECS

ROWS = ("aerodynamic", "rolling_resistance", "inertia", "regenerative_recovery", "transmission_loss",
        "motor_loss", "battery_discharge_loss", "battery_charge_loss", "total")


def cycle_moments(cycle) -> dict[str, float]:
    """Cycle-only sums over the steps: distance, sum(v_bar^3 dt), sum(max(a,0) v_bar dt), T."""
    t = np.asarray(cycle.time_s, float)
    v = np.asarray(cycle.speed_m_s, float)
    dt = np.diff(t)
    v_bar = 0.5 * (v[1:] + v[:-1])  # eq 5-12 mean speed on each step
    dv = np.diff(v)
    distance = float(np.sum(v_bar * dt))
    if not distance > 0:
        raise ValueError(f"drive cycle {getattr(cycle, 'name', '?')} has zero distance")
    return {
        "distance_m": distance,
        "v3_dt_m3_s2": float(np.sum(v_bar ** 3 * dt)),
        "accel_v_dt_m2_s2": float(np.sum(np.where(dv > 0, dv, 0.0) * v_bar)),  # a*dt = dv
        "duration_s": float(t[-1] - t[0]),
        "v2_dt_m2_s": float(np.sum(v_bar ** 2 * dt)),
        "moving_distance_m": distance,  # A acts while moving: A x distance
    }


def energy_breakdown(resampled, params, vehicle_mass_kg, gear_ratio=None, motor_kw=None) -> dict[str, np.ndarray]:
    """Table 5-1 rows in kWh/100 km, each of shape (N,); keys are :data:`ROWS`.

    ``regenerative_recovery`` is negative (it is subtracted in the total, eq 5-21)."""
    m = design_points("vehicle_mass_kg", vehicle_mass_kg)
    n = batch_size(params, PARAM_SPECS, vehicle_mass_kg=m)
    if m.shape[0] != n:
        m = np.broadcast_to(m, (n,))
    p = resolve_params(params, PARAM_SPECS, n)
    mo = cycle_moments(resampled)
    x, T = mo["distance_m"], mo["duration_s"]
    # per-metre energies (J/m = N)
    if rl.uses_road_load(params):  # coast-down A + B v + C v^2 (road_load.py): C v^2 is reported as
        a0, a1, b, c = rl.coefficients(rl.checked(params))  # "aerodynamic", A + B v as "rolling_resistance"
        aero = c * mo["v3_dt_m3_s2"] / x + 0.0 * m
        roll = a0 + a1 * m + b * mo["v2_dt_m2_s"] / x
    else:
        aero = 0.5 * p["air_density_kg_m3"] * p["drag_area_m2"] * mo["v3_dt_m3_s2"] / x  # 5-13
        roll = p["gravity_m_s2"] * m * p["rolling_resistance"]  # 5-14
    inertia = m * mo["accel_v_dt_m2_s2"] / x  # 5-15
    regen = inertia * p["regen_fraction"]  # 5-16
    through = aero + roll + inertia + regen
    gear = through * (1.0 - p["gear_efficiency"])  # 5-17
    motor = (through + gear) * (1.0 - p["motor_efficiency"])  # 5-18
    v_b = p["battery_voltage_v"]
    i_dis = (aero + roll + inertia + gear + motor) * x / (T * v_b)  # mean discharge current
    i_chg = regen * x / (T * v_b)
    batt_dis = i_dis * i_dis * p["battery_discharge_resistance_ohm"] * T / x  # 5-19
    batt_chg = i_chg * i_chg * p["battery_charge_resistance_ohm"] * T / x  # 5-20
    total = aero + roll + inertia - regen + gear + motor + p["battery_loss_weight"] * (batt_dis + batt_chg)  # 5-21
    rows = (aero, roll, inertia, -regen, gear, motor, batt_dis, batt_chg, total)
    zero = 0.0 * m
    return {k: (r + zero) * J_PER_M_TO_KWH_PER_100KM for k, r in zip(ROWS, rows)}


def energy_wh_per_km(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw) -> np.ndarray:
    """Total chapter-5 energy (eq 5-21) in Wh/km, shape (N,). ``gear_ratio``/``motor_kw`` are unused."""
    return energy_breakdown(resampled, params, vehicle_mass_kg)["total"] * 10.0
