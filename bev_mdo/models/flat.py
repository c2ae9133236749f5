"""Flat (inverse-dynamic) DC-motor energy model, thesis eqs 7-18, 7-22..7-27 and 6-34.

Per sample i of a resampled cycle and per design (mass M, gear i_g):

    F   = 1/2 rho CdA v|v| + C_r M g sgn(v) + M a                      (7-18)
    I   = u e F,             u = r_w / (K_m i_g)                       (7-22)
    dI  = u e (rho CdA |v| a + M j)                                    (7-23)
    V   = L dI + R I + K_m w,  K_m w = K_m i_g v / r_w = v / u         (7-24, 7-25)
    P   = I V                                                          (7-26)
    E   = sum_i w_i P_i dt,   E_per_km = E / sum_i v_i dt              (7-27)

Choices (documented deviations):
* gear efficiency: e = 1/eta_g when driving (F >= 0) and e = eta_g when braking (F < 0),
  so the gearbox loses energy in both directions; eq 7-22 divides by eta_g always, which
  would *gain* energy when regenerating.
* regeneration (eq 6-34): braking samples are those with negative traction force (negative
  wheel power); their electrical power is weighted by r, driving samples by 1. The thesis
  writes the indicator as "acceleration < 0"; using the force sign keeps coasting
  decelerations (where drag exceeds inertia) as driving power. Eq 6-34 as printed,
  P - P 1[a<0] r/100, would keep braking power at r = 0 and drop it at r = 100, the reverse of
  eqs 6-32/6-33: the weight r is that equations' reading.
* eq 7-23 as printed (rho CdA v + M dv/dt) is not the derivative of eq 7-18's force; dI uses that
  derivative (rho CdA |v| a + M j, the jerk j = da/dt), an inductive term under 0.2 % of the energy.
* rolling resistance acts only while moving (sgn(v)); eq 7-18 has it also at standstill,
  where it would give a small copper loss at idle.

Since P is a quadratic in M times u^2 plus a linear term in M, the energy is exact from nine
cycle moments summed separately over driving and braking samples. A sample brakes when
M > -A_i/B_i (A_i = drag force >= 0, B_i = C_r g sgn(v) + a < 0), so sorting samples by that
threshold gives the braking moments of any mass by one searchsorted. :func:`energy_wh_per_km`
uses those moments; :func:`energy_wh_per_km_direct` sums the time series (time x N) and
both agree to rounding.
"""
from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from . import road_load as rl
from .common import check_design, check_lengths
from .cycles import Resampled, quadrature
from .params import VEHICLE_SPECS, get_params

FLAT_PARAMS = ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2", "rolling_resistance",
               "wheel_radius_m", "gear_efficiency", "motor_constant_nm_a", "motor_resistance_ohm",
               "motor_inductance_h", "regen_fraction")
_ROAD = ("air_density_kg_m3", "gravity_m_s2", "drag_area_m2", "rolling_resistance")


def _params(params: dict | None) -> dict:
    """Defaults filled in and every value range-checked (scalars stay scalars)."""
    params = params or {}
    return {**get_params(params, FLAT_PARAMS), **rl.checked(params)}


def _road_key(p) -> tuple:
    """Road constants that the cycle moments depend on (scalars only)."""
    if rl.uses_road_load(p):
        return ("road_load",) + tuple(float(p[k]) for k in rl.FLAT_KEYS)
    return tuple(float(p[k]) for k in ("air_density_kg_m3", "drag_area_m2", "rolling_resistance", "gravity_m_s2"))


def traction_force_n(speed_m_s, accel_m_s2, mass_kg, drag_area_m2, rolling_resistance,
                     air_density_kg_m3=VEHICLE_SPECS["air_density_kg_m3"].default,
                     gravity_m_s2=VEHICLE_SPECS["gravity_m_s2"].default):
    """Eq 7-18: F_t = 1/2 rho CdA v|v| + C_r M g sgn(v) + M dv/dt (N)."""
    road = {"air_density_kg_m3": air_density_kg_m3, "drag_area_m2": drag_area_m2,
            "rolling_resistance": rolling_resistance, "gravity_m_s2": gravity_m_s2}
    return rl.road_load_n(road, speed_m_s, mass_kg) + mass_kg * accel_m_s2


def _road_terms(r: Resampled, key: tuple):
    """Per quadrature sample: A (force independent of mass), B (force per kg), A', B' (their
    rates) and the sample weight (s). ``key`` is :func:`_road_key`: (rho, CdA, C_r, g) for
    eq 7-18, or the coast-down coefficients (road_load.py) that replace its drag and rolling terms."""
    v, a, j, w = quadrature(r)
    if key[0] == "road_load":
        road = dict(zip(rl.FLAT_KEYS, key[1:]))
    else:
        road = dict(zip(("air_density_kg_m3", "drag_area_m2", "rolling_resistance", "gravity_m_s2"), key))
    f0, f_m, df0_dv = rl.road_load_terms(road, v)
    return f0, f_m + a, df0_dv * a, j, w


def energy_wh_per_km_direct(resampled: Resampled, params: dict | None, vehicle_mass_kg, gear_ratio,
                            motor_kw=None):
    """Eqs 7-18..7-27 summed over the time series, broadcast as (time, N). Wh/km."""
    p = _params(params)
    m = check_design("vehicle_mass_kg", vehicle_mass_kg)
    ig = check_design("gear_ratio", gear_ratio)
    check_lengths(vehicle_mass_kg=m, gear_ratio=ig, **p)
    col = {k: (v if np.ndim(v) == 0 else np.asarray(v)[None, :]) for k, v in p.items()}
    qv, qa, qj, qw = quadrature(resampled)
    v = qv[:, None]
    a = qa[:, None]
    j = qj[:, None]
    wgt = qw[:, None] if np.ndim(qw) else qw
    M = m[None, :]
    f0, f_m, df0_dv = rl.road_load_terms(col, v)                                 # road_load.py
    F = f0 + f_m * M + M * a                                                      # 7-18
    dF = df0_dv * a + M * j
    braking = F < 0
    eta = col["gear_efficiency"]
    e = np.where(braking, eta, 1.0 / eta)
    k = col["wheel_radius_m"] / (col["motor_constant_nm_a"] * ig[None, :])
    current = k * e * F                                                           # 7-22
    d_current = k * e * dF                                                        # 7-23
    omega = ig[None, :] * v / col["wheel_radius_m"]                               # 7-24
    volt = (col["motor_inductance_h"] * d_current + col["motor_resistance_ohm"] * current
            + col["motor_constant_nm_a"] * omega)                                 # 7-25
    power = current * volt                                                        # 7-26
    power = np.where(braking, col["regen_fraction"] * power, power)               # 6-34
    if np.ndim(qw):
        energy_j = (power * wgt).sum(axis=0)                                      # 7-27
        distance_m = float((qv * qw).sum())
    else:
        energy_j = power.sum(axis=0) * qw                                         # 7-27
        distance_m = qv.sum() * qw
    return energy_j / 3.6 / distance_m


@dataclass(frozen=True)
class FlatMoments:
    """Cycle moments for one resampled cycle and one (rho, CdA, C_r, g)."""

    distance_m: float
    thresholds_kg: np.ndarray   # (K,) sorted braking thresholds
    total: np.ndarray           # (9,) sums over all samples
    braking_cum: np.ndarray     # (K+1, 9) cumulative sums over samples in threshold order


# moment columns: L-terms AA', AB'+A'B, BB'; R-terms A^2, 2AB, B^2; back-EMF Av, Bv; unused 0
def moments(resampled: Resampled, key: tuple) -> FlatMoments:
    """Precompute the flat-model cycle moments (cached per resampled cycle and road constants,
    ``key`` from :func:`_road_key`)."""
    per = _MOMENTS.get(resampled)
    if per is None:
        per = _MOMENTS[resampled] = {}
    hit = per.get(key)
    if hit is not None:
        return hit
    A, B, dA, dB, w = _road_terms(resampled, key)
    v = quadrature(resampled)[0]
    w_col = w[:, None] if np.ndim(w) else w
    cols = np.stack([A * dA, A * dB + dA * B, B * dB, A * A, 2 * A * B, B * B, A * v, B * v,
                     np.zeros_like(A)], axis=1) * w_col
    cand = np.flatnonzero(B < 0)
    thr = -A[cand] / B[cand]
    order = np.argsort(thr, kind="stable")
    cum = np.vstack([np.zeros((1, 9)), np.cumsum(cols[cand[order]], axis=0)])
    dist = float((v * w).sum()) if np.ndim(w) else float(v.sum() * w)
    out = FlatMoments(dist, thr[order], cols.sum(axis=0), cum)
    per[key] = out
    return out


_MOMENTS: "weakref.WeakKeyDictionary[Resampled, dict]" = weakref.WeakKeyDictionary()


def energy_wh_per_km(resampled: Resampled, params: dict | None, vehicle_mass_kg, gear_ratio, motor_kw=None):
    """Flat-model energy per km (Wh/km) for N designs, exact via precomputed cycle moments.

    ``params`` values may be scalars or (N,) arrays; per-point road constants (rho, CdA, C_r,
    g) fall back to the direct time-series sum. ``motor_kw`` is unused (signature shared
    with the other energy models)."""
    p = _params(params)
    road = rl.FLAT_KEYS if rl.uses_road_load(p) else _ROAD
    if any(np.ndim(p[k]) for k in road):
        return energy_wh_per_km_direct(resampled, p, vehicle_mass_kg, gear_ratio)
    m = check_design("vehicle_mass_kg", vehicle_mass_kg)
    ig = check_design("gear_ratio", gear_ratio)
    check_lengths(vehicle_mass_kg=m, gear_ratio=ig, **p)
    mo = moments(resampled, _road_key(p))
    brk = mo.braking_cum[np.searchsorted(mo.thresholds_kg, m, side="left")]      # (N, 9)
    drv = mo.total - brk
    eta, r = p["gear_efficiency"], p["regen_fraction"]
    L, R = p["motor_inductance_h"], p["motor_resistance_ohm"]
    m2 = m * m
    # quadratic part: u^2 e^2 [L(AA' + M(AB'+A'B) + M^2 BB') + R(A^2 + 2MAB + M^2 B^2)]
    def quad(s):
        return L * (s[:, 0] + m * s[:, 1] + m2 * s[:, 2]) + R * (s[:, 3] + m * s[:, 4] + m2 * s[:, 5])

    def lin(s):
        return s[:, 6] + m * s[:, 7]
    u = p["wheel_radius_m"] / (p["motor_constant_nm_a"] * ig)
    energy_j = (u * u * (quad(drv) / (eta * eta) + r * eta * eta * quad(brk))
                + lin(drv) / eta + r * eta * lin(brk))
    return energy_j / 3.6 / mo.distance_m
