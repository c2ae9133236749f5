"""0-100 km/h time (eqs 7-30 / 2-26) with the scaled motor envelope of Fig 2-9 and the tyres' grip.

Motor envelope for a motor of P kW: peak torque tau x P (tau = 3.5 N m/kW, 280 N m at 80 kW)
up to the base speed 1000/tau rad/s (2728 rpm, Appendix A: 2730 rpm), constant power P above
it, and nothing beyond the speed limit (10 500 rpm for every size, ch.3). At the wheels
F = min(T i_g eta_g / r_w, F_grip) - 1/2 rho CdA v^2 - C_r M g, and t = integral_0^v_end M / F dv,
integrated per smooth segment with Gauss-Legendre quadrature. A design that cannot reach v_end
(motor over its speed limit, or no surplus force) has no such time: +inf.

A design that cannot reach 100 km/h is a real design that is merely bad, so the MDO must see it as
infeasible, not as a failed point (a non-finite output fails a point). With ``continuation=True``
(what the acceleration discipline asks for) such a design gets the documented continuation value
``NOT_REACHED_S + NOT_REACHED_S_PER_KM_H x shortfall``: 10 000 s plus 100 s per km/h that its top
speed (:func:`top_speed_m_s`: the speed limit, or where the drive force falls to the road load) lies
below v_end. It is finite, far above any real 0-100 km/h time (the time grows only logarithmically as
the surplus force at v_end falls to zero), and falls as the design moves toward reaching v_end (more
power, a lower ratio), so a gradient-based optimiser started there has a way out; the config refuses an
upper limit on the time at or above ``NOT_REACHED_S``, so such a design is infeasible whatever the
limit, and the evaluate output names it (``not_reached_note``). A time of ``NOT_REACHED_S`` or more is
never a time: it reads back as the top speed, v_end - (t - NOT_REACHED_S) / NOT_REACHED_S_PER_KM_H.

Grip limit (not in the thesis): the drive force cannot exceed F_grip = mu g M s, with mu the
``tyre_grip_coefficient`` and s the ``driven_axle_load_share`` (static, no weight transfer; 1 with
``driven_axles`` 2). Where it binds the force is F_grip - road load from rest up to the corner
v_grip = P eta_g / F_grip, in the constant-power region, which replaces the base speed as the
segment edge. ``tyre_grip_coefficient`` 0 switches it off (the ``thesis`` parameter set).

Battery limit (the thesis' 5C discharge limit, §3.5.3, applied to the run): the motors' shaft power is at
most P_batt eta_bs, P_batt the pack's terminal power at its discharge current limit ``discharge_c_max`` x
capacity (Ah) at ``initial_soc`` (battery.py: eqs 2-12, 2-15; never above ocv^2 / 4R) and eta_bs the
``battery_to_shaft_efficiency`` (0.90, an assumption: motor + inverter at full load). Where it binds the
motor runs at the constant power P_batt eta_bs from the corner v_batt = v_base P_batt eta_bs / P, which
replaces the base speed as the segment edge (F = P_batt eta_bs eta_g / v above it). Given with
``battery_kwh`` (the acceleration discipline always gives it; none: no limit); ``battery_to_shaft_efficiency``
0 switches it off (the ``thesis`` parameter set).
"""
from __future__ import annotations

import numpy as np

from . import battery as bt
from . import road_load as rl
from .common import check_design, check_lengths
from .params import get_params

ACCEL_PARAMS = ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2", "rolling_resistance", "wheel_radius_m",
                "gear_efficiency", "motor_torque_per_kw", "motor_speed_limit_rpm", "tyre_grip_coefficient",
                "driven_axle_load_share", "driven_axles")
# the pack's limit on the run (battery_shaft_power_w)
BATTERY_LIMIT_PARAMS = ("battery_to_shaft_efficiency", "discharge_c_max", "cells_series", "initial_soc")
V_END_M_S = 100.0 / 3.6
NOT_REACHED_S = 1.0e4           # the continuation's floor: a time at or above it means "does not reach v_end"
NOT_REACHED_S_PER_KM_H = 100.0  # and its slope, per km/h of top speed short of v_end
_X, _W = np.polynomial.legendre.leggauss(24)


def grip_force_n(vehicle_mass_kg, p, two_axles=False):
    """Largest drive force the driven tyres carry, mu g M s (N); +inf with ``tyre_grip_coefficient`` 0."""
    mu, axles, share = p["tyre_grip_coefficient"], p.get("driven_axles", 1.0), p["driven_axle_load_share"]
    if type(mu) is float and type(axles) is float and type(share) is float:  # the usual: no array work
        return mu * p["gravity_m_s2"] * (1.0 if two_axles or axles == 2.0 else share) * vehicle_mass_kg \
            if mu > 0 else np.inf
    share = np.where(two_axles | (np.asarray(axles) == 2.0), 1.0, share)
    return np.where(mu > 0, mu * p["gravity_m_s2"] * share * vehicle_mass_kg, np.inf)


def battery_shaft_power_w(battery_kwh, p):
    """The most shaft power the pack lets the motors give together in the 0-100 km/h run (W), (N,) or a
    float: P_batt eta_bs (module doc), P_batt = (ocv - I R) I (eq 2-12) at I = ``discharge_c_max`` x capacity
    (§3.5.3: 5C), or at ocv / 2R where that is less (the pack's largest power ocv^2 / 4R: more current gives
    less); +inf where ``battery_to_shaft_efficiency`` is 0 or ``battery_kwh`` is None (no limit)."""
    eta_bs = p["battery_to_shaft_efficiency"]
    if battery_kwh is None or not np.any(np.asarray(eta_bs) > 0):
        return np.inf
    pack = bt.pack_for_energy(battery_kwh, p["cells_series"])
    ocv_v, r_ohm = pack.ocv(p["initial_soc"]), pack.resistance(p["initial_soc"], False)  # eq 2-15, discharging
    current_a = np.minimum(p["discharge_c_max"] * pack.capacity_ah, ocv_v / (2.0 * r_ohm))
    p_batt_w = np.minimum(bt.power_at_current_w(current_a, ocv_v, r_ohm), bt.max_discharge_power_w(ocv_v, r_ohm))
    return np.where(np.asarray(eta_bs) > 0, p_batt_w * eta_bs, np.inf)


def grip_corner_m_s(lo, hi, torque_force_n, power_w, grip_n, v_end_m_s):
    """Speed where the envelope F = torque_force_n + power_w / v of a smooth segment [lo, hi] ((S, N)
    arrays) falls to the grip ``grip_n`` inside the segment, (N,); ``v_end_m_s`` (an edge already) where
    it does not (the grip binds throughout, nowhere, or up to an edge). There is one at most: F falls
    through the grip inside a segment only where a motor runs at constant power, and from there on F
    stays below P eta / v, which only falls (no shift lifts F above it)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = power_w / (grip_n - torque_force_n)
    inside = (grip_n > torque_force_n) & (cross > lo) & (cross < hi)
    return np.min(np.where(inside, cross, v_end_m_s), axis=0)


def wheel_force_n(speed_m_s, motor_kw, gear_ratio, vehicle_mass_kg, p, grip_n=np.inf, battery_kw=None):
    """Net accelerating force at full motor envelope within the grip ``grip_n`` (N), the motor's power at most
    ``battery_kw`` (the battery limit where it binds, +inf elsewhere; None: none); broadcasts speed against
    designs."""
    v = np.asarray(speed_m_s, float)
    omega = gear_ratio * v / p["wheel_radius_m"]
    t_max = p["motor_torque_per_kw"] * motor_kw
    omega_base = 1000.0 / p["motor_torque_per_kw"]
    omega_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0
    torque = np.where(omega <= omega_base, t_max, 1000.0 * motor_kw / np.maximum(omega, 1e-300))
    if battery_kw is not None:  # the battery's constant power: F = P_batt eta_bs eta_g / v at the wheels
        torque = np.minimum(torque, 1000.0 * battery_kw / np.maximum(omega, 1e-300))
    torque = np.where(omega <= omega_lim * (1 + 1e-12), torque, 0.0)
    road = rl.road_load_n(p, v, vehicle_mass_kg)  # eq 2-3, or the coast-down A + B v + C v^2
    f = torque * gear_ratio * p["gear_efficiency"] / p["wheel_radius_m"]
    if grip_n is not np.inf:
        np.minimum(f, grip_n, out=f)  # in place: a new (nodes, N) array cost 20 % of the batch's time
    f -= road
    return f


def top_speed_m_s(force_n, v_high_m_s):
    """Highest speed reached from rest at full envelope (m/s), per design: ``v_high_m_s`` (the speed limit,
    or v_end) where ``force_n`` (net force at speeds (N,), N) is still positive there, else the first speed
    where it falls to zero, by bisection on [0, v_high] (the force is non-increasing in speed)."""
    lo, hi = np.zeros_like(v_high_m_s), np.array(v_high_m_s, float)
    held = force_n(hi) > 0
    for _ in range(60):  # 2^-60 of the interval: to the last bits
        mid = 0.5 * (lo + hi)
        up = force_n(mid) > 0
        lo, hi = np.where(up, mid, lo), np.where(up, hi, mid)
    return np.where(held, v_high_m_s, lo)


def not_reached_s(top_m_s, v_end_m_s=V_END_M_S):
    """The continuation value of a design whose top speed ``top_m_s`` is below ``v_end_m_s`` (module doc)."""
    return NOT_REACHED_S + NOT_REACHED_S_PER_KM_H * 3.6 * np.maximum(v_end_m_s - top_m_s, 0.0)


def not_reached_note(time_s, v_end_m_s=V_END_M_S) -> str | None:
    """One line for the user when ``time_s`` is the continuation value, else None."""
    if not np.isfinite(time_s) or time_s < NOT_REACHED_S:
        return None
    top = 3.6 * v_end_m_s - (time_s - NOT_REACHED_S) / NOT_REACHED_S_PER_KM_H
    return (f"the design cannot reach {3.6 * v_end_m_s:g} km/h (top speed {top:.1f} km/h): its 0-100 km/h time "
            f"{time_s:.6g} s is the continuation value {NOT_REACHED_S:g} s + {NOT_REACHED_S_PER_KM_H:g} s per km/h short,"
            " not a time")


def accel_time_s(motor_kw, gear_ratio, vehicle_mass_kg, params=None, v_end_m_s=V_END_M_S, continuation=False,
                 battery_kwh=None):
    """Time from rest to ``v_end_m_s`` (default 100 km/h) in s for N designs (eq 7-30); a design that cannot
    reach it: +inf, or with ``continuation`` the continuation value; within the battery limit of a pack of
    ``battery_kwh`` (None: no limit) (module doc)."""
    pk = check_design("motor_kw", motor_kw)
    ig = check_design("gear_ratio", gear_ratio)
    m = check_design("vehicle_mass_kg", vehicle_mass_kg)
    kwh = None if battery_kwh is None else check_design("battery_kwh", battery_kwh)
    p = {**get_params(params, ACCEL_PARAMS + BATTERY_LIMIT_PARAMS), **rl.checked(params)}
    if not pk.shape == ig.shape == m.shape == (pk.shape if kwh is None else kwh.shape) \
            or any(type(x) is not float for x in p.values()):
        n = check_lengths(motor_kw=pk, gear_ratio=ig, vehicle_mass_kg=m, **({} if kwh is None else
                                                                           {"battery_kwh": kwh}), **p)
        pk, ig, m = (np.broadcast_to(a, (n,)) for a in (pk, ig, m))
        kwh = None if kwh is None else np.broadcast_to(kwh, (n,))
    grip = grip_force_n(m, p)
    v_base = (1000.0 / p["motor_torque_per_kw"]) * p["wheel_radius_m"] / ig
    v_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0 * p["wheel_radius_m"] / ig
    # the battery limit: the motor at the constant power P_batt eta_bs from v_batt = v_base P_batt eta_bs / P
    # (below the base speed) where that is less than its own P; nothing changes where it is not
    shaft_kw = battery_shaft_power_w(kwh, p) / 1000.0
    binds = shaft_kw < pk
    power_kw, battery_kw = (pk, None) if not np.any(binds) else (np.where(binds, shaft_kw, pk),
                                                                 np.where(binds, shaft_kw, np.inf)[None, :])
    if battery_kw is not None:
        v_base = np.where(binds, v_base * shaft_kw / pk, v_base)
    # the one corner below v_end: the base speed (or battery corner), or where the grip stops binding
    # (P eta / v = F_grip, beyond that corner exactly when the grip binds at rest); the force is smooth on
    # either side
    if grip is np.inf:
        v1, grip_row = np.minimum(v_base, v_end_m_s), grip
    else:
        v_grip = (1000.0 * p["gear_efficiency"]) * power_kw / grip
        v1, grip_row = np.minimum(np.maximum(v_base, v_grip), v_end_m_s), grip[None, :]
    # One force evaluation for everything: the 24 Gauss nodes of each segment (0..v1 and
    # v1..v_end), then v_end and v1 for the feasibility check. (Filled in place: the same values
    # as stacking the segments, with fewer temporaries on the one-point path.)
    nodes = len(_X)
    half0, half1 = 0.5 * v1, 0.5 * (v_end_m_s - v1)
    v = np.empty((2 * nodes + 2, v1.size))
    v[:nodes] = half0 + half0 * _X[:, None]                                        # mid + half x
    v[nodes:2 * nodes] = 0.5 * (v_end_m_s + v1) + half1 * _X[:, None]
    v[2 * nodes] = v_end_m_s
    v[2 * nodes + 1] = v1
    pb = {k: (x if type(x) is float or np.ndim(x) == 0 else x[None, :]) for k, x in p.items()}
    f = wheel_force_n(v, pk[None, :], ig[None, :], m[None, :], pb, grip_row, battery_kw)
    mrow = m[None, :]
    with np.errstate(divide="ignore"):
        total = (half0 * np.sum(_W[:, None] * mrow / f[:nodes], axis=0)             # dt = M/F dv
                 + half1 * np.sum(_W[:, None] * mrow / f[nodes:2 * nodes], axis=0))
    f_end, f_base = f[2 * nodes], f[2 * nodes + 1]
    ok = (v_lim >= v_end_m_s) & (f_end > 0) & (f_base > 0)
    if continuation and not ok.all():
        cap = None if battery_kw is None else battery_kw[0]
        top = top_speed_m_s(lambda s: wheel_force_n(s, pk, ig, m, p, grip, cap), np.minimum(v_lim, v_end_m_s))
        return np.where(ok, total, not_reached_s(top, v_end_m_s)).reshape(pk.shape)
    return np.where(ok, total, np.inf).reshape(pk.shape)


def accel_time_0_100_s(motor_kw, gear_ratio, vehicle_mass_kg, params=None, continuation=False, battery_kwh=None):
    """0-100 km/h time in s (eqs 7-30 / 2-26); ``continuation``, ``battery_kwh``: see :func:`accel_time_s`."""
    return accel_time_s(motor_kw, gear_ratio, vehicle_mass_kg, params, V_END_M_S, continuation, battery_kwh)
