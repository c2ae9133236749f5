"""Wall-to-wheel energy model ("chain"): every stage from the charging socket to the tyre.

Per step of the resampled cycle (the step's mean speed and acceleration, eqs 6-50/6-51) and per
design point, vectorised as (moving steps, N):

1. road load and inertia, F = F_road(v) + M (1 + f_rot) a (eq 2-3 / 7-18, or the coast-down
   A + B v + C v^2 of road_load.py);
2. transmission (eqs 2-4, 2-5): w = v i_g / r_w, T = F r_w / (i_g eta_g) driving, F r_w eta_g / i_g
   braking;
3. regeneration limits (axle share, peak torque, power, minimum speed); friction brakes the rest;
4. motor + inverter, a scalable loss model replacing the thesis' map (eqs 2-7/2-8):
   P_loss = P_r (c_0 + c_w s + c_cu tau^2) while moving, with tau = |T| / T_pk, s = w / w_b, plus
   the technology terms (induction machines, two-speed gear, second axle);
5. battery (eq 5-19/5-20 form): P_batt = P_el + R (P_el / V)^2, plus ``aux_power_w`` for the
   whole cycle;
6. charger: E_wall = E_batt / ``charger_efficiency``; ``ChainResult.energy_wh_per_km`` is E_wall
   per km, the figure EPA measures; range (eq 7-28) uses E_batt.

Every parameter of every stage: docs/validation.md, "chain: wall to wheel". A design whose motor
cannot deliver the cycle's demand (torque above T_pk or power above P_r at any sample) still gets
its energy (demand clipped to nothing; the loss is counted at the demanded torque) and
``follows = False`` in :func:`simulate`. The shipped calibration (``vehicle.parameter_set:
epa2022_chain``) was fitted on the EPA 2022 fleet (docs/validation.md, bev_mdo/data/parameter_sets/).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import road_load as rl
from .common import batch_size, design_points, resolve_params
from .cycles import Resampled
from .params import CHAIN_SPECS

PARAM_SPECS = CHAIN_SPECS


@dataclass
class ChainResult:
    """Per design point (N,)."""

    energy_wh_per_km: np.ndarray          # from the wall
    battery_wh_per_km: np.ndarray         # at the battery terminals, auxiliaries included
    wheel_wh_per_km: np.ndarray           # positive wheel work
    regen_wh_per_km: np.ndarray           # returned to the battery (>= 0)
    follows: np.ndarray                   # the motor delivers the cycle's torque and power
    torque_margin_nm: np.ndarray          # min over the cycle of T_pk - T (driving)
    power_margin_kw: np.ndarray           # min over the cycle of P_r - T w (driving)
    distance_m: float


def _col(x):
    return x if np.ndim(x) == 0 else np.asarray(x, float)[None, :]


def resolve(params, n: int) -> dict:
    return {**resolve_params(params, PARAM_SPECS, n, real=True), **rl.checked(params)}


def simulate(resampled: Resampled, params, vehicle_mass_kg, gear_ratio, motor_kw) -> ChainResult:
    """Wall-to-wheel energy of N designs on one resampled cycle (see the module doc)."""
    m = design_points("vehicle_mass_kg", vehicle_mass_kg, real=True)
    ig = design_points("gear_ratio", gear_ratio, real=True)
    kw = design_points("motor_kw", motor_kw, real=True)
    extra = {k: params[k] for k in rl.FLAT_KEYS if params and k in params and np.ndim(params[k]) == 1}
    n = max(batch_size(params, PARAM_SPECS, vehicle_mass_kg=m, gear_ratio=ig, motor_kw=kw),
            *(np.size(x) for x in extra.values()), 1)
    m, ig, kw = (np.broadcast_to(a, (n,)) for a in (m, ig, kw))
    p = {k: _col(v) for k, v in resolve(params, n).items()}
    v, a, w, dur, dist, v_lo, v_hi = _steps(resampled)
    M = m[None, :]
    force = rl.road_load_n(p, v, M) + M * (1.0 + p["rotating_mass_fraction"]) * a
    gc = np.asarray(p["gear_count"])  # 1 or 2, and driven_axles 1 or 2 (checked with the parameters)
    # a two-speed gearbox and its clutch lose two_speed_efficiency_loss more (§3.3.2, as quasi_static.py)
    r_w, eta = p["wheel_radius_m"], p["gear_efficiency"] - np.where(gc == 2.0, p["two_speed_efficiency_loss"], 0.0)
    i_g, p_r = ig[None, :], kw[None, :] * 1e3
    omega = v * i_g / r_w
    t_pk = p["motor_torque_per_kw"] * kw[None, :]
    driving = force >= 0
    t_drive = np.where(driving, force * r_w / (i_g * eta), 0.0)
    t_brake = np.where(driving, 0.0, p["regen_axle_share"] * force * r_w * eta / i_g)  # <= 0
    p_regen_cap = np.minimum(p_r, p["regen_max_power_kw"] * 1e3)
    t_regen_cap = np.minimum(t_pk, p_regen_cap / np.maximum(omega, 1e-9))
    # share of the step spent at or above the regeneration cut-off speed (exact for a linear step)
    v_min = p["regen_min_speed_m_s"]
    phi = np.clip((v_hi - v_min) / np.maximum(v_hi - v_lo, 1e-12), 0.0, 1.0)
    phi = np.where(v_lo >= v_min, 1.0, np.where(v_hi < v_min, 0.0, phi))
    t_regen = np.where(phi > 0, np.maximum(t_brake, -t_regen_cap), 0.0)
    torque = t_drive + t_regen
    w_base = 1000.0 / p["motor_torque_per_kw"]
    tau = np.abs(torque) / t_pk
    # all-wheel drive: the second axle's gear and bearing drag while moving (as quasi_static.py's)
    idle = (p_r * (p["motor_loss_standby_fraction"] + p["motor_loss_speed_fraction"] * omega / w_base)
            + (p["driven_axles"] - 1.0) * p["second_axle_drag_w"])
    loss = idle + p_r * p["motor_loss_copper_fraction"] * tau * tau
    # induction machines: rotor copper (slip) loss ~ shaft power (§2.2.3: 1-2 % below synchronous machines)
    loss = loss + p["induction_loss_fraction"] * p["induction_machine_share"] * np.abs(torque * omega)
    p_el = torque * omega + loss
    # braking: regenerate where it returns more than idling costs; otherwise idle (friction brakes act)
    # (for the share phi of the step; the rest of the step below the cut-off speed idles)
    p_el = np.where(driving, p_el, phi * np.minimum(p_el, idle) + (1.0 - phi) * idle)
    volt = p["battery_voltage_v"]
    r_b = np.where(p_el >= 0, p["battery_discharge_resistance_ohm"], p["battery_charge_resistance_ohm"])
    p_batt = p_el + r_b * (p_el / volt) ** 2
    e_batt = w[:, 0] @ p_batt + np.broadcast_to(p["aux_power_w"], (1, n))[0] * dur
    km = dist / 1e3
    eta_chg = np.broadcast_to(p["charger_efficiency"], (1, n))[0]
    batt = e_batt / 3600.0 / km
    follows_t = np.where(driving, t_pk - t_drive, np.inf).min(axis=0)
    follows_p = np.where(driving, p_r - t_drive * omega, np.inf).min(axis=0) / 1e3
    return ChainResult(batt / eta_chg, batt,
                       w[:, 0] @ np.maximum(force * v, 0.0) / 3600.0 / km,
                       -(w[:, 0] @ np.minimum(p_batt, 0.0)) / 3600.0 / km,
                       (follows_t >= 0) & (follows_p >= -1e-9), follows_t, follows_p, dist)


_STEPS: dict = {}


def _steps(r: Resampled):
    """Moving steps of a cycle: mean speed (6-50), acceleration (6-51) and length, as (K, 1)
    columns, plus the duration and distance of the whole cycle. A piecewise-linear trace is
    integrated exactly for distance and kinetic energy; standstill steps carry only the
    auxiliary load (the motor is off), so they are left out of the (K, N) arrays."""
    key = r.key()
    hit = _STEPS.get(key)
    if hit is not None:
        return hit
    t, v = np.asarray(r.time_s, float), np.asarray(r.speed_m_s, float)
    h = np.diff(t)
    v_bar = 0.5 * (v[1:] + v[:-1])
    a = np.diff(v) / h
    dist = float(np.sum(v_bar * h))
    if not dist > 0:
        raise ValueError(f"drive cycle {r.name} has zero distance")
    keep = v_bar > 0
    lo, hi = np.minimum(v[1:], v[:-1]), np.maximum(v[1:], v[:-1])
    out = (v_bar[keep, None], a[keep, None], h[keep, None], float(t[-1] - t[0]), dist, lo[keep, None], hi[keep, None])
    if len(_STEPS) > 64:
        _STEPS.clear()
    _STEPS[key] = out
    return out


def energy_wh_per_km(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw) -> np.ndarray:
    """Energy from the wall per km (Wh/km), shape (N,)."""
    return simulate(resampled, params, vehicle_mass_kg, gear_ratio, motor_kw).energy_wh_per_km
