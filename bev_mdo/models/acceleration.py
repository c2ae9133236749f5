"""0-100 km/h time (eqs 7-30 / 2-26) with the scaled motor envelope of Fig 2-9.

Motor envelope for a motor of P kW: peak torque tau x P (tau = 3.5 N m/kW, 280 N m at 80 kW)
up to the base speed 1000/tau rad/s (2728 rpm, Appendix A: 2730 rpm), constant power P above
it, and nothing beyond the speed limit (10 500 rpm for every size, ch.3). At the wheels
F = T i_g eta_g / r_w - 1/2 rho CdA v^2 - C_r M g, and t = integral_0^v_end M / F dv,
integrated per envelope segment with Gauss-Legendre quadrature (the integrand is smooth
within each segment). A design that cannot reach v_end (motor over its speed limit, or no
surplus force) gets +inf.
"""
from __future__ import annotations

import numpy as np

from . import road_load as rl
from .common import check_design
from .params import get_params

ACCEL_PARAMS = ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2", "rolling_resistance", "wheel_radius_m",
                "gear_efficiency", "motor_torque_per_kw", "motor_speed_limit_rpm")
V_END_M_S = 100.0 / 3.6
_X, _W = np.polynomial.legendre.leggauss(24)


def wheel_force_n(speed_m_s, motor_kw, gear_ratio, vehicle_mass_kg, p):
    """Net accelerating force at full motor envelope (N); broadcasts speed against designs."""
    v = np.asarray(speed_m_s, float)
    omega = gear_ratio * v / p["wheel_radius_m"]
    t_max = p["motor_torque_per_kw"] * motor_kw
    omega_base = 1000.0 / p["motor_torque_per_kw"]
    omega_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0
    torque = np.where(omega <= omega_base, t_max, 1000.0 * motor_kw / np.maximum(omega, 1e-300))
    torque = np.where(omega <= omega_lim * (1 + 1e-12), torque, 0.0)
    road = rl.road_load_n(p, v, vehicle_mass_kg)  # eq 2-3, or the coast-down A + B v + C v^2
    return torque * gear_ratio * p["gear_efficiency"] / p["wheel_radius_m"] - road


def accel_time_s(motor_kw, gear_ratio, vehicle_mass_kg, params=None, v_end_m_s=V_END_M_S):
    """Time from rest to ``v_end_m_s`` (default 100 km/h) in s for N designs (eq 7-30)."""
    pk = check_design("motor_kw", motor_kw)
    ig = check_design("gear_ratio", gear_ratio)
    m = check_design("vehicle_mass_kg", vehicle_mass_kg)
    if not pk.shape == ig.shape == m.shape:
        pk, ig, m = np.broadcast_arrays(pk, ig, m)
    p = {**get_params(params, ACCEL_PARAMS), **rl.checked(params)}
    v_base = (1000.0 / p["motor_torque_per_kw"]) * p["wheel_radius_m"] / ig
    v_lim = p["motor_speed_limit_rpm"] * np.pi / 30.0 * p["wheel_radius_m"] / ig
    v1 = np.minimum(v_base, v_end_m_s)
    # One force evaluation for everything: the 24 Gauss nodes of each envelope segment
    # (0..v1 and v1..v_end), then v_end and v1 for the feasibility check. (Filled in place:
    # the same values as stacking the segments, with fewer temporaries on the one-point path.)
    nodes = len(_X)
    half0, half1 = 0.5 * v1, 0.5 * (v_end_m_s - v1)
    v = np.empty((2 * nodes + 2, v1.size))
    v[:nodes] = half0 + half0 * _X[:, None]                                        # mid + half x
    v[nodes:2 * nodes] = 0.5 * (v_end_m_s + v1) + half1 * _X[:, None]
    v[2 * nodes] = v_end_m_s
    v[2 * nodes + 1] = v1
    pb = {k: (x if type(x) is float or np.ndim(x) == 0 else x[None, :]) for k, x in p.items()}
    f = wheel_force_n(v, pk[None, :], ig[None, :], m[None, :], pb)
    mrow = m[None, :]
    with np.errstate(divide="ignore"):
        total = (half0 * np.sum(_W[:, None] * mrow / f[:nodes], axis=0)             # dt = M/F dv
                 + half1 * np.sum(_W[:, None] * mrow / f[nodes:2 * nodes], axis=0))
    f_end, f_base = f[2 * nodes], f[2 * nodes + 1]
    ok = (v_lim >= v_end_m_s) & (f_end > 0) & (f_base > 0)
    return np.where(ok, total, np.inf).reshape(pk.shape)


def accel_time_0_100_s(motor_kw, gear_ratio, vehicle_mass_kg, params=None):
    """0-100 km/h time in s (eqs 7-30 / 2-26)."""
    return accel_time_s(motor_kw, gear_ratio, vehicle_mass_kg, params, V_END_M_S)
