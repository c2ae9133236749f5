"""0-100 km/h time of the chapter-4 topologies (eqs 2-26 / 4-5): SM-SA (one or two speeds), DM-DA, IWM-SA,
IWM-DA, with the motors and axles of topology.py.

The rules are acceleration.py's (its module doc; there for single-speed SM-SA, the acceleration discipline's
fast path): every motor's envelope at the wheels, within the tyres' grip (two driven axles carry all the
weight) and the battery limit (the motors' shaft powers together at most P_batt eta_bs, at the wheels
P_batt eta_bs eta_g / v), minus the road load; t = int M / F(v) dv by Gauss-Legendre per segment between the
corners, where F is smooth.
"""
from __future__ import annotations

import numpy as np

from . import acceleration
from . import quasi_static as qs
from . import road_load as rl
from .params import QUASI_STATIC_SPECS
from .topology import _axles, _prepare, _t_max

V_END_M_S = acceleration.V_END_M_S
_X, _W = np.polynomial.legendre.leggauss(24)


def _torque_and_power(parts, r_w):
    """Of the envelope F = torque_n + power_w / v on each segment ((S, N) each): the force of the axles at
    peak torque (N) and the wheel power of those at constant power (W); ``parts`` as ``envelope`` gives them
    at the segments' middles."""
    torque_n = sum(np.where(tq == a.t_peak, a.count * tq * ratio * a.eta / r_w, 0.0) for a, ratio, tq in parts)
    power_w = sum(np.where((tq < a.t_peak) & (tq > 0), a.count * a.kw * 1e3 * a.eta, 0.0) for a, _, tq in parts)
    return torque_n, power_w


def _battery_corners_m_s(lo, hi, torque_n, power_w, battery_w, v_end_m_s):
    """The speeds where the motors' envelope torque_n + power_w / v of the segments [lo, hi] ((S, N)) meets
    the battery's battery_w / v (battery_w: P_batt eta_bs eta_g, (N,), W), (K, N) in rising order, K the most
    of any design (v_end_m_s where a design has fewer). One per segment at most: v F = torque_n v + power_w
    rises in v there."""
    with np.errstate(divide="ignore", invalid="ignore"):
        cross = (battery_w - power_w) / torque_n
    inside = (torque_n > 0) & (battery_w > power_w) & (cross > lo) & (cross < hi)
    k = int(np.max(np.sum(inside, axis=0), initial=0))
    return np.sort(np.where(inside, cross, v_end_m_s), axis=0)[:k]


def _limit_corners(edges, envelope, r_w, battery_w, grip_n, v_end_m_s):
    """``edges`` ((E, N), sorted) with the corners of the limits added: where the motors' envelope meets the
    battery's P_batt eta_bs eta_g / v (``battery_w``, None: no limit), then where the envelope within it
    falls to the grip ``grip_n`` (None: no limit; F = P eta / v (+ the torque-limited axles) = grip)."""
    if battery_w is not None:
        parts = list(envelope(0.5 * (edges[:-1] + edges[1:])))
        cross = _battery_corners_m_s(edges[:-1], edges[1:], *_torque_and_power(parts, r_w), battery_w, v_end_m_s)
        edges = np.sort(np.concatenate([edges, cross]), axis=0)
    if grip_n is not None:
        mid = 0.5 * (edges[:-1] + edges[1:])
        torque_n, power_w = _torque_and_power(list(envelope(mid)), r_w)  # each segment's torque-, power-limited
        if battery_w is not None:  # where the battery binds, the segment is at its constant power
            held = battery_w < torque_n * mid + power_w
            torque_n, power_w = np.where(held, 0.0, torque_n), np.where(held, battery_w, power_w)
        v_grip = acceleration.grip_corner_m_s(edges[:-1], edges[1:], torque_n, power_w, grip_n, v_end_m_s)
        edges = np.sort(np.concatenate([edges, v_grip[None]]), axis=0)
    return edges


def accel_time_s(topology, vehicle_mass_kg, motor_kw, gear_ratio=None, motor_rear_kw=None, gear_ratio_rear=None,
                 params=None, v_end_m_s=V_END_M_S, continuation=False, battery_kwh=None):
    """0-100 km/h time (eqs 2-26 / 4-5): t = int M / F(v) dv, F every motor's envelope at the wheels within
    the tyres' grip (``acceleration.grip_force_n``) and, with ``battery_kwh``, the battery limit on the
    motors' total shaft power (``acceleration.battery_shaft_power_w``; None: no limit), minus road load,
    Gauss-Legendre per segment between the corners (base speeds, the two-speed shift and speed limits, where
    the battery starts binding, where the grip stops binding). SM-SA single speed equals
    ``acceleration.accel_time_0_100_s``; two-speed follows eq 2-6 (gear 2 from the shift speed, efficiency
    less the 2-point penalty). +inf for a geared motor over its speed limit before ``v_end`` or a non-positive
    surplus force; with ``continuation`` the continuation value of its top speed instead (``acceleration``
    module doc)."""
    p = {k: s.default for k, s in QUASI_STATIC_SPECS.items()}
    p.update({k: np.asarray(v, float) for k, v in (params or {}).items()
              if k in QUASI_STATIC_SPECS or k in rl.FLAT_KEYS})
    t, m, ig, kw, p, kw_r, ig_r = _prepare(p, topology, vehicle_mass_kg, motor_kw,
                                           qs.DEFAULT_BATTERY_KWH if battery_kwh is None else battery_kwh,
                                           gear_ratio, motor_rear_kw, gear_ratio_rear)
    r_w, sm_sa = p["wheel_radius_m"], t.name == "SM-SA"
    two = (p["gear_count"] == 2.0) & sm_sa
    axles = _axles(t, p, kw, kw_r, ig, ig_r, qs.default_map())
    grip = acceleration.grip_force_n(m, p, t.two_axles)
    ig2 = v_shift = None
    if sm_sa:
        eta2 = p["gear_efficiency"] - np.where(two, p["two_speed_efficiency_loss"], 0.0)
        axles[0].eta = np.broadcast_to(eta2, kw.shape)
        ig2 = np.broadcast_to(np.where(two, p["gear_ratio_2"], ig), kw.shape)
        v_shift = np.broadcast_to(np.where(two, p["shift_speed_m_s"], np.inf), kw.shape)
    # battery limit on the sum of the motors (every axle of a design has the same eta_g): at the wheels
    # P_batt eta_bs eta_g / v where the motors' rated powers exceed P_batt eta_bs, +inf elsewhere (unchanged)
    shaft_w = acceleration.battery_shaft_power_w(None if battery_kwh is None else p["battery_kwh"], p)
    binds = shaft_w < sum(a.count * a.kw * 1e3 for a in axles)
    battery = bool(np.any(binds))
    battery_w = np.where(binds, shaft_w * axles[0].eta, np.inf) if battery else None

    def envelope(v):  # per axle: ratio and motor torque at the speeds v (..., N)
        for a in axles:
            ratio = np.where(v >= v_shift, ig2, a.ratio) if sm_sa else a.ratio
            yield a, ratio, _t_max(a, v / r_w * ratio)

    def force(v):  # within the battery and the grip (the motors' sum in the order it had before either)
        road = rl.road_load_n(p, v, m)
        f = -road
        for a, ratio, tq in envelope(v):
            f = f + a.count * tq * ratio * a.eta / r_w
        if battery:
            with np.errstate(divide="ignore"):
                np.minimum(f, battery_w / v - road, out=f)
        return f if no_grip else np.minimum(f, grip - road, out=f)

    # no grip limit where the peak drive force (of the larger gear with two) is within it
    peak = sum(a.count * a.t_peak * (np.maximum(a.ratio, ig2) if sm_sa else a.ratio) * a.eta / r_w for a in axles)
    # corners: per axle and gear the base speed, and the speed limit, which no motor may pass before v_end (two
    # speeds: gear 1 up to the shift); with one speed that is v_end or later, so not an edge below v_end
    corners, ok, shifts, no_grip = [], np.ones(m.shape, bool), bool(np.any(two)), bool(np.all(peak <= grip))
    reach = np.full(m.shape, v_end_m_s)  # the first speed limit met before v_end (the continuation's top speed)
    for a in axles:
        for ratio, top in ([(a.ratio, np.minimum(v_shift, v_end_m_s)), (ig2, np.where(two, v_end_m_s, 0.0))]
                           if shifts else [(a.ratio, v_end_m_s)]):
            v_lim = a.w_lim * r_w / ratio
            corners += [a.kw * 1e3 / a.t_peak * r_w / ratio, *([v_lim] if shifts else [])]
            ok &= v_lim >= top * (1 - 1e-12)
            reach = np.where(v_lim >= top * (1 - 1e-12), reach, np.minimum(reach, v_lim))
    edges = np.stack([0.0 * m, *corners, *([v_shift] if shifts else []), v_end_m_s + 0.0 * m])
    edges = np.clip(np.sort(edges, axis=0), 0.0, v_end_m_s)  # (B+2, N)
    edges = _limit_corners(edges, envelope, r_w, battery_w, None if no_grip else grip, v_end_m_s)
    half = 0.5 * (edges[1:] - edges[:-1])
    v = (edges[:-1] + half)[None] + half[None] * _X[:, None, None]  # (24, B+1, N)
    f = force(v)
    with np.errstate(divide="ignore", invalid="ignore"):
        total = np.sum(half * np.sum(_W[:, None, None] * m / f, axis=0), axis=0)
    ok &= np.all(f > 0, axis=(0, 1)) & (force(np.full(m.shape, v_end_m_s)) > 0)
    if continuation and not ok.all():
        top = acceleration.top_speed_m_s(force, reach)
        return np.where(ok, total, acceleration.not_reached_s(top, v_end_m_s))
    return np.where(ok, total, np.inf)
