"""Can a single-speed motor follow a drive cycle? The steps of a cycle its full envelope cannot drive.

The envelope is the acceleration model's (acceleration.py: peak torque ``motor_torque_per_kw`` x P up to
the base speed, constant power P above it, nothing beyond ``motor_speed_limit_rpm``, within the tyres'
grip), so "cannot follow" and the 0-100 km/h time agree. Each step is judged as the quasi-static model
drives it (eqs 6-50, 6-51): the net force M (v1 - v0) / h at the step's mean speed, where the motor must
also turn within its speed limit, so that a design whose ``drive_torque_margin_nm`` and
``motor_speed_margin_rad_s`` are >= 0 is never called short (a user trial: the step's higher speed
flagged the shipped topology study's optimum, 26 N short at 3 of 5,215 steps). The energy models compute the
energy of the cycle's demand whether or not the motor delivers it; this is what says that it does not.
"""
from __future__ import annotations

import numpy as np

from . import road_load as rl
from .acceleration import ACCEL_PARAMS, grip_force_n, wheel_force_n
from .params import get_params


def steps_not_followed(time_s, speed_m_s, params, vehicle_mass_kg, gear_ratio, motor_kw):
    """(count, worst, over_speed) per design, each (N,): the cycle steps the motor cannot drive, the largest
    shortfall of net force over them (N, 0 where none), and how many of them turn it over its speed limit."""
    count, worst, _, over = _in_blocks(time_s, speed_m_s, params, vehicle_mass_kg, gear_ratio, motor_kw)
    return count, worst, over


def drive_force_margin_n(time_s, speed_m_s, params, vehicle_mass_kg, gear_ratio, motor_kw):
    """Per design (N,): the least, over the cycle's moving steps, of the envelope's net force minus the
    force the step needs (N; +inf for a cycle that never moves). A design with a margin >= 0 that turns
    its motor within its speed limit (``motor_speed_max_rad_s``) follows every step: constrain both so that
    an optimiser steers clear of one that does not."""
    return _in_blocks(time_s, speed_m_s, params, vehicle_mass_kg, gear_ratio, motor_kw)[2]


def _in_blocks(time_s, speed_m_s, params, vehicle_mass_kg, gear_ratio, motor_kw):
    t, v = np.asarray(time_s, float), np.asarray(speed_m_s, float)
    p = {**get_params(params, ACCEL_PARAMS), **rl.checked(params)}
    m, ig, kw = (np.atleast_1d(np.asarray(x, float)) for x in (vehicle_mass_kg, gear_ratio, motor_kw))
    n = max(m.size, ig.size, kw.size)
    m, ig, kw = (np.broadcast_to(x, (n,)) for x in (m, ig, kw))
    p = {k: np.broadcast_to(np.asarray(x, float), (n,)) if np.ndim(x) else x for k, x in p.items()}
    count, worst, margin, over = np.zeros(n, np.int64), np.zeros(n), np.zeros(n), np.zeros(n, np.int64)
    step = max(1, _CELLS // max(len(v), 1))  # designs per block: (steps x designs) arrays stay small at any batch
    for s in range(0, n, step):
        b = slice(s, s + step)
        count[b], worst[b], margin[b], over[b] = _block(t, v, {k: (x[b] if np.ndim(x) else x) for k, x in p.items()},
                                               m[b], ig[b], kw[b])
    return count, worst, margin, over


_CELLS = 1 << 20  # steps x designs per block (about 8 MB per array)


def _block(t, v, p, m, ig, kw):
    v_bar = 0.5 * (v[1:] + v[:-1])[:, None]  # 6-50, as the quasi-static model drives the step
    need = m[None, :] * (np.diff(v) / np.diff(t))[:, None]  # 6-51
    pb = {k: (x if np.ndim(x) == 0 else x[None, :]) for k, x in p.items()}
    have = wheel_force_n(v_bar, kw[None, :], ig[None, :], m[None, :], pb, grip_force_n(m[None, :], pb))
    over_speed = ig[None, :] * v_bar / pb["wheel_radius_m"] > pb["motor_speed_limit_rpm"] * np.pi / 30.0 * (1 + 1e-12)
    short = need - have
    moving = v_bar > 0
    bad = moving & ((short > 1e-9 * (np.abs(need) + np.abs(have) + 1.0)) | over_speed)
    return (bad.sum(axis=0), np.where(bad, np.maximum(short, 0.0), 0.0).max(axis=0, initial=0.0),
            np.where(moving, -short, np.inf).min(axis=0, initial=np.inf), (moving & over_speed).sum(axis=0))
