"""Compiled per-design loops (numba) of the quasi-static and topology models.

The same equations as ``quasi_static.demand`` / ``topology._demand`` (the per-step battery
demand, eqs 2-1..2-8, 2-25, §2.3.4 rules 1-3, §4.2 torque split) and as the battery loops
``quasi_static.integrate_energy`` / ``integrate_range`` (eqs 2-9..2-17, rule 4), written as one
loop per design point instead of numpy passes over (time, design) arrays. Those numpy
functions stay as the reference the tests compare with (energy and range to 1e-12).

* The demand of a design is one signed power per step: ``>= 0`` motoring (drawn from the
  battery), ``< 0`` regenerating (offered to it; the battery applies rule 4 and the 2C cap).
* Range steps only the battery over the range cycle's precomputed demand, cycle after cycle,
  and stops each design at its own crossing of ``final_soc``; steps with zero demand leave the
  battery as it is (no current, no energy) and are skipped.
* Motor maps are looked up in the bilinear form of ``topology.electrical_power_w``; numpy's
  ``interp`` is re-implemented operation for operation (``_interp``).
* Designs run in parallel over the host's cores (``prange``); each design's loop is sequential
  and independent of the others, so results do not depend on the thread count.

Compiled code is cached next to this file (``cache=True``); where that directory is not
writable numba uses the user cache, and where there is none the functions compile on first
use in every process (about a few seconds, see docs/performance.md) instead of failing.
"""
from __future__ import annotations

import math

import numpy as np
import numba
from numba import prange

_PENALTY_W_PER_NM = 1e6  # as topology._PENALTY_W_PER_NM: motoring torque over the envelope
_EFFICIENCY_FLOOR = 0.05  # as motor_map.EFFICIENCY_FLOOR


def _jit(**options):
    """numba.njit with an on-disk cache when a cache directory is available, else without."""
    def wrap(fn):
        try:
            return numba.njit(cache=True, error_model="numpy", **options)(fn)
        except RuntimeError:  # "cannot cache function ...: no locator available" (read-only install)
            return numba.njit(cache=False, error_model="numpy", **options)(fn)
    return wrap


@_jit(inline="always")
def _interp(x, xp, fp, table, inv_h, slopes):
    """np.interp for one value, the same operations as numpy's C loop (clamped at both ends).
    ``table``/``inv_h``/``slopes`` (``grid_table``) find the interval without a search and hold
    numpy's slopes (fp[j+1] - fp[j]) / (xp[j+1] - xp[j])."""
    n = xp.shape[0]
    if x > xp[n - 1]:
        return fp[n - 1]
    if x < xp[0]:
        return fp[0]
    j = table[min(int((x - xp[0]) * inv_h), table.shape[0] - 1)]
    while j > 0 and xp[j] > x:  # guard against rounding of the table position
        j -= 1
    while j < n - 1 and xp[j + 1] <= x:  # largest j with xp[j] <= x
        j += 1
    if j == n - 1 or xp[j] == x:
        return fp[j]
    slope = slopes[j]
    r = slope * (x - xp[j]) + fp[j]
    if math.isnan(r):
        r = slope * (x - xp[j + 1]) + fp[j + 1]
        if math.isnan(r) and fp[j] == fp[j + 1]:
            r = fp[j]
    return r


def grid_table(xp, fp) -> tuple:
    """(table, inv_h, slopes) for ``_interp`` of ``fp`` on the increasing grid ``xp``: table[m] is
    the interval that holds xp[0] + m h, with h half the smallest spacing."""
    xp, fp = np.asarray(xp, float), np.asarray(fp, float)
    h = 0.5 * float(np.min(np.diff(xp)))
    m = int(np.ceil((xp[-1] - xp[0]) / h)) + 2
    table = np.searchsorted(xp, xp[0] + h * np.arange(m), side="right") - 1
    return np.clip(table, 0, len(xp) - 1).astype(np.int64), 1.0 / h, np.diff(fp) / np.diff(xp)


def map_tuple(wg, tg, eff, ref_kw: float, regen_rows: bool) -> tuple:
    """The motor map as the compiled loops take it: (speed grid, torque grid, efficiency, speed
    indices, torque indices, speed table, 1/h, slopes, torque table, 1/h, slopes, unit kW, regen rows)."""
    wg, tg = np.array(wg, dtype=float), np.array(tg, dtype=float)
    iw, it = np.arange(len(wg), dtype=float), np.arange(len(tg), dtype=float)
    return (wg, tg, np.array(eff, dtype=float), iw, it, *grid_table(wg, iw), *grid_table(tg, it), float(ref_kw),
            bool(regen_rows))


@_jit(inline="always")
def _speed_index(w, mp):
    """Fractional speed-grid position of |w| (the speed half of the bilinear lookup)."""
    return _interp(abs(w), mp[0], mp[3], mp[5], mp[6], mp[7])


@_jit(inline="always")
def _electrical_w(torque, w, fi, kw, mp):
    """Electrical power of one motor at (T, w), eq 2-7 with the Fig 2-9 torque scaling
    (``topology.electrical_power_w`` for one point); ``fi`` = ``_speed_index(w, mp)``."""
    wg, tg, eff, it = mp[0], mp[1], mp[2], mp[4]
    tu = torque * (mp[11] / kw)
    if not mp[12]:
        tu = abs(tu)
    fj = _interp(tu, tg, it, mp[8], mp[9], mp[10])
    i0 = min(int(fi), wg.shape[0] - 2)
    j0 = min(int(fj), tg.shape[0] - 2)
    a = fi - i0
    b = fj - j0
    eta = (1 - a) * ((1 - b) * eff[i0, j0] + b * eff[i0, j0 + 1]) + a * ((1 - b) * eff[i0 + 1, j0]
                                                                         + b * eff[i0 + 1, j0 + 1])
    eta = max(eta, _EFFICIENCY_FLOOR)
    pm = torque * w
    return pm / eta if pm >= 0 else pm * eta


@_jit(inline="always")
def _road_force_n(v, a, mass, a0, a1, b, c):
    """Road load (road_load.road_load_n) plus inertia M a (2-3, 6-53) at mean speed v >= 0."""
    base = a0 + a1 * mass
    if v > 0:
        rl = base + v * (b + c * v)
    else:
        rl = base * np.sign(v) + v * (b + c * abs(v))
    return rl + mass * a


@_jit(inline="always")
def _t_max(w, w_lim, t_peak, kw):
    """Motor envelope: peak torque, then constant power, 0 beyond the speed limit."""
    if w <= w_lim:
        return min(t_peak, kw * 1e3 / max(w, 1e-9))
    return 0.0


@_jit(parallel=True)
def single_motor_demand(v, acc, mass, a0, a1, b, c, r_w, ratio1, ratio2, shift_m_s, two, best_gear, eta_g,
                        kw, t_peak, w_lim, regen_min_m_s, decel_min, mp):
    """SM-SA demand (``quasi_static.demand``): per step the gear (eq 2-6, or the least-power gear
    the envelope allows), motor torque and speed, rules 1-3, the map. Returns the signed power
    (N, K), the top motor speed (N,) and the least motoring torque margin T_max - T_m (N,)."""
    n_pts, n_steps = mass.shape[0], v.shape[0]
    power = np.empty((n_pts, n_steps))
    speed_max = np.empty(n_pts)
    margin = np.empty(n_pts)
    for n in prange(n_pts):
        w_top = -np.inf
        least = np.inf
        for k in range(n_steps):
            force = _road_force_n(v[k], acc[k], mass[n], a0[n], a1[n], b[n], c[n])
            t_w = force * r_w[n]  # 2-1
            driving = force >= 0
            allowed = (not driving) and v[k] >= regen_min_m_s[n] and acc[k] >= decel_min[n]
            ratio = ratio2[n] if (two[n] and v[k] >= shift_m_s[n]) else ratio1[n]  # 2-6
            if best_gear[n]:  # per step the gear of least electrical power that the envelope allows
                cost0 = cost1 = np.inf
                for g in range(2):
                    r = ratio1[n] if g == 0 else ratio2[n]
                    w_m = v[k] / r_w[n] * r
                    t_drive = t_w / (r * eta_g[n]) if driving else 0.0
                    tmax = _t_max(w_m, w_lim[n], t_peak[n], kw[n])
                    t_regen = max(t_w * eta_g[n] / r, -tmax) if allowed else 0.0
                    p_el = _electrical_w(t_drive + t_regen, w_m, _speed_index(w_m, mp), kw[n], mp)
                    cost = p_el if (w_m <= w_lim[n] and t_drive <= tmax) else np.inf
                    if g == 0:
                        cost0 = cost
                    else:
                        cost1 = cost
                pick2 = cost1 < cost0 or (np.isinf(cost0) and np.isinf(cost1) and ratio != ratio1[n])
                ratio = ratio2[n] if pick2 else ratio1[n]
            w_m = v[k] / r_w[n] * ratio  # 2-2, 2-4
            t_drive = t_w / (ratio * eta_g[n]) if driving else 0.0  # 2-5
            tmax = _t_max(w_m, w_lim[n], t_peak[n], kw[n])
            t_regen = max(t_w * eta_g[n] / ratio, -tmax) if allowed else 0.0  # 2-25
            power[n, k] = _electrical_w(t_drive + t_regen, w_m, _speed_index(w_m, mp), kw[n], mp)
            w_top = max(w_top, w_m)
            if driving:
                least = min(least, tmax - t_drive)
        speed_max[n] = w_top
        margin[n] = least
    return power, speed_max, margin


@_jit(inline="always")
def _axle_power(count, ratio, eta, kw, tw, w, fi, tmax, driving, allowed, mp):
    """Electrical power of an axle carrying wheel torque ``tw`` and its motoring overload
    (``topology._axle_power`` for one point)."""
    if driving:
        tm = tw / (count * ratio * eta)  # 2-5
        over = max(tm - tmax, 0.0)
    else:
        over = 0.0
        tm = max(tw * eta / (count * ratio), -tmax) if allowed else 0.0  # 2-25, rules 2-3
    return count * _electrical_w(tm, w, fi, kw, mp), over


@_jit(parallel=True)
def axle_demand(v, acc, mass, a0, a1, b, c, r_w, regen_min_m_s, decel_min, two_axles, grid, fine,
                count_f, ratio_f, eta_f, kw_f, t_peak_f, w_lim_f, count_r, ratio_r, eta_r, kw_r, t_peak_r, w_lim_r,
                mp):
    """Demand of the topologies of ``topology._demand`` (one or two driven axles, one map): with two
    axles the front share of wheel torque minimising the electrical power per step (coarse grid,
    then the fine grid around its argmin, ``topology.best_split``). Returns the signed power (N, K),
    the top motor speed (N,) and the least wheel-torque margin (N,)."""
    n_pts, n_steps = mass.shape[0], v.shape[0]
    power = np.empty((n_pts, n_steps))
    speed_max = np.empty(n_pts)
    margin = np.empty(n_pts)
    for n in prange(n_pts):
        w_top = -np.inf
        least = np.inf
        for k in range(n_steps):
            force = _road_force_n(v[k], acc[k], mass[n], a0[n], a1[n], b[n], c[n])
            tw = force * r_w[n]  # 2-1, all driven wheels
            driving = force >= 0
            allowed = (not driving) and v[k] >= regen_min_m_s[n] and acc[k] >= decel_min[n]
            wf = v[k] / r_w[n] * ratio_f[n]
            tmf = _t_max(wf, w_lim_f[n], t_peak_f[n], kw_f[n])
            cap = 0.0 + count_f * tmf * ratio_f[n] * eta_f[n]
            w_top = max(w_top, wf)
            fif = _speed_index(wf, mp)
            if not two_axles:
                p, _ = _axle_power(count_f, ratio_f[n], eta_f[n], kw_f[n], tw, wf, fif, tmf, driving, allowed, mp)
            else:
                wr = v[k] / r_w[n] * ratio_r[n]
                tmr = _t_max(wr, w_lim_r[n], t_peak_r[n], kw_r[n])
                cap = cap + count_r * tmr * ratio_r[n] * eta_r[n]
                w_top = max(w_top, wr)
                p = 0.0
                if driving or allowed:  # else no motor torque on either axle at any share: p = 0
                    fir = _speed_index(wr, mp)
                    s0 = 0.0
                    for stage in range(2):
                        shares = grid if stage == 0 else fine
                        best = np.inf
                        for j in range(shares.shape[0]):
                            s = shares[j] if stage == 0 else min(max(s0 + shares[j], 0.0), 1.0)
                            pf, of = _axle_power(count_f, ratio_f[n], eta_f[n], kw_f[n], tw * s, wf, fif, tmf,
                                                 driving, allowed, mp)
                            pr, orr = _axle_power(count_r, ratio_r[n], eta_r[n], kw_r[n], tw * (1.0 - s), wr, fir,
                                                  tmr, driving, allowed, mp)
                            score = (pf + pr) + _PENALTY_W_PER_NM * (of + orr)
                            if score < best or j == 0:  # the first minimum, as np.argmin
                                best = score
                                s_best = s
                                p = pf + pr
                        s0 = s_best
            power[n, k] = p
            if driving:
                least = min(least, cap - tw)
        speed_max[n] = w_top
        margin[n] = least
    return power, speed_max, margin


@_jit(inline="always")
def _step(soc, demand_w, dt, ns, n_par, q_c, i_chg, soc_max, s_tab, ocv_tab, rd_tab, rc_tab, s_find, s_inv, ocv_slopes, rd_slopes, rc_slopes):
    """One battery step (``quasi_static._Battery.step``): terminal power, current, resistance,
    whether the demand was within ocv^2/4R, and the new SOC (2-9..2-15, rule 4, 2C cap)."""
    p_drive = demand_w if demand_w > 0 else 0.0
    p_regen = demand_w if (demand_w < 0 and not soc > soc_max) else 0.0  # rule 4: SOC > 90 %
    voc = ns * _interp(soc, s_tab, ocv_tab, s_find, s_inv, ocv_slopes)
    r = ns * (_interp(soc, s_tab, rc_tab, s_find, s_inv, rc_slopes) if p_regen < 0
              else _interp(soc, s_tab, rd_tab, s_find, s_inv, rd_slopes)) / n_par
    p_chg_lim = (voc - (-i_chg) * r) * (-i_chg)  # 2-12 at the 2C charge cap
    p_max = voc * voc / (4.0 * r)
    power = min(p_drive, p_max) + max(p_regen, p_chg_lim)
    v_bt = 0.5 * (voc + math.sqrt(max(voc * voc - 4.0 * power * r, 0.0)))  # 2-13, 2-14
    i = power / v_bt  # 2-11
    return power, i, r, p_drive <= p_max, soc - i * dt / q_c  # 2-9, 2-10


@_jit(parallel=True)
def battery_energy(demand_w, dt, soc0, ns, n_par, q_c, i_chg, i_dis, soc_max, w_loss,
                   s_tab, ocv_tab, rd_tab, rc_tab, s_find, s_inv, ocv_slopes, rd_slopes, rc_slopes):
    """Step each design's battery over its demand (``quasi_static.integrate_energy``): energy drawn
    and returned (J, 2-16, 2-17), final SOC, and the current and power feasibility flags."""
    n_pts, n_steps = demand_w.shape
    energy = np.zeros(n_pts)
    regen = np.zeros(n_pts)
    soc_end = np.empty(n_pts)
    current_ok = np.ones(n_pts, np.bool_)
    power_ok = np.ones(n_pts, np.bool_)
    for n in prange(n_pts):
        soc = soc0[n]
        e = 0.0
        back = 0.0
        for k in range(n_steps):
            x = demand_w[n, k]
            if x == 0.0:  # no current, no energy, SOC unchanged
                continue
            power, i, r, within, soc = _step(soc, x, dt[k], ns[n], n_par[n], q_c[n], i_chg[n], soc_max[n],
                                             s_tab, ocv_tab, rd_tab, rc_tab, s_find, s_inv, ocv_slopes, rd_slopes, rc_slopes)
            if not within:
                power_ok[n] = False
            if not i <= i_dis[n] * (1 + 1e-12):
                current_ok[n] = False
            e += (power + w_loss[n] * i * i * r) * dt[k]
            back -= min(power, 0.0) * dt[k]
        energy[n] = e
        regen[n] = back
        soc_end[n] = soc
    return energy, regen, soc_end, current_ok, power_ok


@_jit(parallel=True)
def battery_range_m(demand_w, dt, step_m, soc_stop, max_repeats, ns, n_par, q_c, i_chg, soc_max,
                    s_tab, ocv_tab, rd_tab, rc_tab, s_find, s_inv, ocv_slopes, rd_slopes, rc_slopes):
    """Distance (m) from 100 % SOC to ``soc_stop`` repeating the cycle's demand
    (``quasi_static.integrate_range``), the crossing interpolated inside its step; inf if the
    battery is still above after ``max_repeats`` cycles."""
    n_pts, n_steps = demand_w.shape
    out = np.full(n_pts, np.inf)
    for n in prange(n_pts):
        soc = 1.0
        travelled = 0.0
        done = False
        for _ in range(max_repeats):
            for k in range(n_steps):
                x = demand_w[n, k]
                if x != 0.0:
                    _, _, _, _, new = _step(soc, x, dt[k], ns[n], n_par[n], q_c[n], i_chg[n], soc_max[n],
                                            s_tab, ocv_tab, rd_tab, rc_tab, s_find, s_inv, ocv_slopes, rd_slopes, rc_slopes)
                    if new <= soc_stop[n]:
                        frac = (soc - soc_stop[n]) / max(soc - new, 1e-300)
                        out[n] = travelled + frac * step_m[k]
                        done = True
                        break
                    soc = new
                travelled += step_m[k]
            if done:
                break
    return out
