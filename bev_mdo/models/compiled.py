"""Compiled per-design loops (numba) of the quasi-static and topology models: the demand here,
the battery in compiled_battery.py.

The same equations as ``quasi_static.demand`` / ``topology._demand`` (the per-step battery
demand, eqs 2-1..2-8, 2-25, §2.3.4 rules 1-3, §4.2 torque split) and as the battery loops
``quasi_static.integrate_energy`` / ``integrate_range`` (eqs 2-9..2-17, rule 4), written as one
loop per design point instead of numpy passes over (time, design) arrays. Those numpy
functions stay as the reference the tests compare with (energy and range to 1e-12).

* The demand of a design is one signed power per step: ``>= 0`` motoring (drawn from the
  battery), ``< 0`` regenerating (offered to it; the battery applies rule 4 and the 2C cap).
* A step's demand depends on its (mean speed, acceleration) alone, so it is computed once per
  distinct pair of the cycle (``quasi_static.step_pairs``) and the battery reads each step's.
* Motor maps are looked up as ``motor_map.MotorMap.efficiency_at`` does, bilinear through numpy's
  ``interp``, re-implemented operation for operation (``_interp``), without branches on where
  x falls (the split's lookups jump from share to share).
* Designs run in parallel over the host's cores (``prange``); each design's loop is sequential
  and independent of the others, so results do not depend on the thread count.
* Two compiled kernels (``_drive_demand`` here for every topology, ``compiled_battery._battery``
  for energy and range); the per-step helpers are inlined into them (numba ``inline="always"``: in
  these parallel loops that is several times faster than calls, and one call site each keeps the
  compile short).

Compiled code is cached next to this file (``cache=True``); where that directory is not
writable numba uses the user cache (``NUMBA_CACHE_DIR`` chooses another), and where there is
none the kernels compile on first use in every process (see docs/performance.md) instead of
failing.
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
def _interp(x, xp, fp, table, inv_h, slopes, lo, hi):
    """np.interp for one value, clamped at both ends, with the grid's tables from ``grid_table``:
    slope_j (x - xp[j]) + fp[j], the operations of numpy's C loop, on the largest j with xp[j] <= x.
    ``slopes`` holds numpy's (fp[j+1] - fp[j]) / (xp[j+1] - xp[j]) and 0 after the last point, so a
    clamped x, or one on a grid point, gives fp[j] (slope x 0 + fp[j]) as numpy does.
    ``table``/``inv_h`` find the interval without a search and without branches: x jumps from call
    to call (the split's shares), so a branch on x's place in its table cell would be mispredicted.
    The table position is x's to a few ulps and a table cell (h) is half the least spacing, so x's
    interval is the cell's or one of its neighbours: the step down or up reads the cell's interval
    bounds ``lo``/``hi``, loaded beside its interval, not after it."""
    n = xp.shape[0]
    xc = min(max(x, xp[0]), xp[n - 1])  # np.interp clamps: fp[0] below the grid, fp[n-1] above
    m = min(int((xc - xp[0]) * inv_h), table.shape[0] - 1)
    j = table[m] - int(xc < lo[m]) + int(xc >= hi[m])  # largest j with xp[j] <= x
    return slopes[j] * (xc - xp[j]) + fp[j]


def grid_table(xp, fp) -> tuple:
    """(table, inv_h, slopes, lo, hi) for ``_interp`` of ``fp`` on the increasing grid ``xp``:
    table[m] is the interval that holds xp[0] + m h, with h half the smallest spacing, and lo[m],
    hi[m] that interval's ends (hi inf for the last grid point); slopes as ``_interp`` reads them."""
    xp, fp = np.asarray(xp, float), np.asarray(fp, float)
    h = 0.5 * float(np.min(np.diff(xp)))
    m = int(np.ceil((xp[-1] - xp[0]) / h)) + 2
    table = np.clip(np.searchsorted(xp, xp[0] + h * np.arange(m), side="right") - 1, 0, len(xp) - 1).astype(np.int64)
    return table, 1.0 / h, np.append(np.diff(fp) / np.diff(xp), 0.0), xp[table], np.append(xp, np.inf)[table + 1]


def map_tuple(wg, tg, eff, ref_kw: float, regen_rows: bool) -> tuple:
    """The motor map as the compiled loops take it: (speed grid, torque grid, efficiency, speed
    indices, torque indices, the speed grid's ``grid_table`` (5), the torque grid's (5), unit kW,
    regen rows)."""
    wg, tg = np.array(wg, dtype=float), np.array(tg, dtype=float)
    iw, it = np.arange(len(wg), dtype=float), np.arange(len(tg), dtype=float)
    return (wg, tg, np.array(eff, dtype=float), iw, it, *grid_table(wg, iw), *grid_table(tg, it), float(ref_kw),
            bool(regen_rows))


@_jit(inline="always")
def _speed_row(w, mp):
    """The speed half of the bilinear lookup at |w|, computed once per motor speed: the map row i0
    below it (a float: numba's array analysis fails on a tuple of tuples of mixed types) and the
    fraction a of the way to row i0 + 1."""
    fi = _interp(abs(w), mp[0], mp[3], mp[5], mp[6], mp[7], mp[8], mp[9])
    i0 = min(int(fi), mp[0].shape[0] - 2)
    return float(i0), fi - i0


def loss_tuple(coefficients=None) -> np.ndarray:
    """A loss model (``loss_model.LossModel.as_tuple``) as the compiled loops take it: [1, k_cu,
    k_inv, k_fe, k_fr, P_0, e]; [0, ...] = the map."""
    if coefficients is None:
        return np.zeros(7)
    return np.array([1.0, *coefficients], dtype=float)


@_jit(inline="always")
def _electrical_w(torque, w, row, scale, mp, loss):
    """Electrical power of one motor at (T, w), eq 2-7 with the Fig 2-9 torque scaling
    (``MotorMap.electrical_power_w`` for one point); ``row`` = ``_speed_row(w, mp)``, ``scale`` =
    reference kW / motor kW. No torque: T w (0, the map not read). With a loss model (``loss[0]``
    = 1) T w plus its loss while turning (``loss_model.LossModel.electrical_power_w``)."""
    if loss[0] != 0.0:
        aw = abs(w)
        extra = 0.0
        if aw > 0:
            extra = (loss[1] * torque * torque * scale + loss[2] * abs(torque)
                     + (loss[3] * aw + loss[4] * aw * aw + loss[5]) / scale ** loss[6])
        return torque * w + extra
    if torque == 0.0:
        return torque * w  # pm / eta and pm * eta of pm = +-0
    tg, eff, it = mp[1], mp[2], mp[4]
    tu = torque * scale
    if not mp[16]:
        tu = abs(tu)
    fj = _interp(tu, tg, it, mp[10], mp[11], mp[12], mp[13], mp[14])
    i0, a = int(row[0]), row[1]
    j0 = min(int(fj), tg.shape[0] - 2)
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


# columns of the per-design table ``cols`` (N, len(COLUMNS)) that ``drive_demand`` takes
COLUMNS = ("mass", "a0", "a1", "b", "c", "r_w", "regen_min_m_s", "decel_min",
           "ratio", "eta", "kw", "scale", "t_peak", "w_lim", "count",  # front axle (SM-SA: the motor, gear 1)
           "ratio_r", "eta_r", "kw_r", "scale_r", "t_peak_r", "w_lim_r", "count_r",  # rear axle
           "ratio_2", "shift_m_s", "two_speed", "best_gear",  # SM-SA two-speed gearbox
           "regen_share", "axles", "moving_load_w")  # share of braking the motors take; SM-SA machines, load
(_M, _A0, _A1, _B, _C, _RW, _VMIN, _DMIN, _RATIO, _ETA, _KW, _SCALE, _TPK, _WLIM, _COUNT) = range(15)
_REAR = COLUMNS.index("ratio_r") - _RATIO  # offset of a rear-axle column from its front one
_RATIO2, _SHIFT, _TWO, _BEST, _SHARE, _AXLES, _LOAD = (COLUMNS.index(k) for k in (
    "ratio_2", "shift_m_s", "two_speed", "best_gear", "regen_share", "axles", "moving_load_w"))


@_jit(inline="always")
def _single_motor_step(x, v, t_w, driving, allowed, mp, loss):
    """SM-SA at one step (``quasi_static.demand``): the gear (eq 2-6, or the least-power gear the
    envelope allows), motor torque and speed, rules 2-3, the map (or the loss model, on ``axles``
    equal machines plus the loads while moving). (power, motor speed, T_max - T_m)."""
    axles = x[_AXLES]
    ratio1, ratio2, eta_g, kw, w_lim, t_pk = x[_RATIO], x[_RATIO2], x[_ETA], x[_KW], x[_WLIM], x[_TPK]
    ratio = ratio2 if (x[_TWO] != 0.0 and v >= x[_SHIFT]) else ratio1  # 2-6
    cost0 = np.inf
    p_el = w_m = tmax = t_drive = 0.0
    # g = 0, 1: gear 1 and 2 when the design picks per step the gear of least electrical power
    # that the envelope allows; g = 2: the gear used (one map lookup site, for compile time)
    for g in range(0 if x[_BEST] != 0.0 else 2, 3):
        r = ratio1 if g == 0 else (ratio2 if g == 1 else ratio)
        w_m = v / x[_RW] * r  # 2-2, 2-4
        t_drive = t_w / (r * eta_g) if driving else 0.0  # 2-5
        tmax = _t_max(w_m, w_lim, t_pk, kw)
        t_regen = max(t_w * eta_g / r * x[_SHARE], -tmax) if allowed else 0.0  # 2-25
        if loss[0] != 0.0:
            p_el = axles * _electrical_w((t_drive + t_regen) / axles, w_m, (0.0, 0.0), x[_SCALE], mp, loss)
        else:
            p_el = _electrical_w(t_drive + t_regen, w_m, _speed_row(w_m, mp), x[_SCALE], mp, loss)
        p_el = p_el + (x[_LOAD] if v > 0 else 0.0)  # quasi_static.moving_load_w
        cost = p_el if (w_m <= w_lim and t_drive <= tmax) else np.inf
        if g == 0:
            cost0 = cost
        elif g == 1:
            pick2 = cost < cost0 or (np.isinf(cost0) and np.isinf(cost) and ratio != ratio1)
            ratio = ratio2 if pick2 else ratio1
    return p_el, w_m, tmax - t_drive


@_jit(inline="always")
def _axle(x, o, w, tmax, mp):
    """An axle (columns from ``o``: 0 front, ``_REAR`` rear) at one step, as the split reads it,
    computed once per step: count, count x ratio, count x ratio x eta (2-5), eta, motor scale, motor
    speed, the speed half of its map lookups (``_speed_row``) and its torque envelope."""
    count, ratio, eta = x[_COUNT + o], x[_RATIO + o], x[_ETA + o]
    i0, a = _speed_row(w, mp)
    return count, count * ratio, count * ratio * eta, eta, x[_SCALE + o], w, i0, a, tmax


@_jit(inline="always")
def _axle_power(ax, share, tw, driving, allowed, mp, loss):
    """Electrical power of an axle (``_axle``) carrying wheel torque ``tw`` and its motoring
    overload (``topology._axle_power`` for one point)."""
    count, cr, cre, eta, scale, w, i0, a, tmax = ax
    if driving:
        tm = tw / cre  # 2-5
        over = max(tm - tmax, 0.0)
    else:
        over = 0.0
        tm = max(tw * eta / cr * share, -tmax) if allowed else 0.0  # 2-25, rules 2-3
    return count * _electrical_w(tm, w, (i0, a), scale, mp, loss), over


@_jit(inline="always")
def _split_power(axf, axr, share, s, t_w, driving, allowed, mp, loss):
    """Power and score of one front share ``s`` (front axle at ``s``, rear at ``1 - s``)."""
    pp, of = _axle_power(axf, share, t_w * s, driving, allowed, mp, loss)
    pr, orr = _axle_power(axr, share, t_w * (1.0 - s), driving, allowed, mp, loss)
    pp, of = pp + pr, of + orr
    return pp, pp + _PENALTY_W_PER_NM * of  # topology.best_split's selection score


@_jit(inline="always")
def _axle_step(x, v, t_w, driving, allowed, two_axles, grid, fine, score, power, mp, loss):
    """One or two driven axles at one step (``topology._demand``): with two, the front share of
    wheel torque of least electrical power (coarse ``grid`` and the two envelope shares, then ``fine``
    around their argmin, the first minimum as np.argmin; a fine share equal to a coarse one reuses its
    value); one axle carries it all (share 1). ``score`` and ``power``: scratch of the grid's length
    plus 2 plus ``fine``'s. (power, top motor speed, wheel-torque margin)."""
    o = _REAR
    wf = v / x[_RW] * x[_RATIO]
    tmf = _t_max(wf, x[_WLIM], x[_TPK], x[_KW])
    cap = 0.0 + x[_COUNT] * tmf * x[_RATIO] * x[_ETA]
    wr = tmr = 0.0
    if two_axles:
        wr = v / x[_RW] * x[_RATIO + o]
        tmr = _t_max(wr, x[_WLIM + o], x[_TPK + o], x[_KW + o])
        cap = cap + x[_COUNT + o] * tmr * x[_RATIO + o] * x[_ETA + o]
    w_top = max(wf, wr) if two_axles else wf
    if not (driving or allowed) and loss[0] == 0.0:  # no motor torque on any axle at any share (a loss
        # model's idle motors still lose)
        return 0.0, w_top, cap - t_w
    if t_w == 0.0 and (loss[0] == 0.0 or v == 0.0):  # standing (or no wheel torque): no torque at any
        # share, and no idle loss without speed: every share's power is 0
        return 0.0, w_top, cap - t_w
    axf, share = _axle(x, 0, wf, tmf, mp), x[_SHARE]
    if not two_axles:
        return _axle_power(axf, share, t_w, driving, allowed, mp, loss)[0], w_top, cap - t_w
    axr = _axle(x, o, wr, tmr, mp)
    n_coarse = grid.shape[0]
    for i in range(n_coarse):
        power[i], score[i] = _split_power(axf, axr, share, grid[i], t_w, driving, allowed, mp, loss)
    # the shares at which the front, then the rear, motor reaches its envelope (topology._envelope_shares)
    env_f, env_r = 1.0, 0.0
    if driving and t_w > 0:
        env_f = min(max(tmf * axf[2] / t_w, 0.0), 1.0)
        env_r = min(max(1.0 - tmr * axr[2] / t_w, 0.0), 1.0)
    power[n_coarse], score[n_coarse] = _split_power(axf, axr, share, env_f, t_w, driving, allowed, mp, loss)
    power[n_coarse + 1], score[n_coarse + 1] = _split_power(axf, axr, share, env_r, t_w, driving, allowed, mp, loss)
    n_cand = n_coarse + 2
    jc = 0
    for i in range(1, n_cand):  # the first minimum, as np.argmin
        jc = i if score[i] < score[jc] else jc
    s0 = grid[jc] if jc < n_coarse else (env_f if jc == n_coarse else env_r)
    n_fine = fine.shape[0]
    for i in range(n_fine):
        s = min(max(s0 + fine[i], 0.0), 1.0)
        q = jc if s == s0 else -1
        if jc < n_coarse:
            for c in range(max(jc - 1, 0), min(jc + 2, n_coarse)):  # a fine share equal to a coarse one
                if grid[c] == s:
                    q = c
        if q >= 0:
            power[n_cand + i], score[n_cand + i] = power[q], score[q]
        else:
            power[n_cand + i], score[n_cand + i] = _split_power(axf, axr, share, s, t_w, driving, allowed,
                                                                mp, loss)
    jf = n_cand
    for i in range(n_cand + 1, n_cand + n_fine):
        jf = i if score[i] < score[jf] else jf
    return power[jf], w_top, cap - t_w


def drive_demand(*args):
    """``_drive_demand``, its designs taken 4 at a time by whichever thread is free (the battery
    loops take one block of lanes): not in halves fixed up front, so a core that the host takes
    for a while does not leave the other waiting at the end (set here: numba does not cache a kernel
    that sets it)."""
    with numba.parallel_chunksize(4):
        return _drive_demand(*args)


@_jit(parallel=True)
def _drive_demand(v, acc, cols, single_motor, two_axles, grid, fine, mp, loss):
    """Battery demand of every design (row of ``cols``, see ``COLUMNS``) at each (mean speed ``v``,
    acceleration ``acc``) pair (``quasi_static.step_pairs``): SM-SA (``single_motor``) or one/two
    driven axles. Returns the signed power (N, U), the top motor speed (N,) and the least motoring margin (N,):
    T_max - T_m of the motor (SM-SA) or the axles' wheel torque capacity minus demand. ``loss``:
    ``loss_tuple`` (the map when its first entry is 0)."""
    n_pts, n_steps = cols.shape[0], v.shape[0]
    power = np.empty((n_pts, n_steps))
    speed_max = np.empty(n_pts)
    margin = np.empty(n_pts)
    for n in prange(n_pts):
        x = cols[n]
        score = np.empty(grid.shape[0] + 2 + fine.shape[0])
        scratch = np.empty(grid.shape[0] + 2 + fine.shape[0])
        w_top = -np.inf
        least = np.inf
        for k in range(n_steps):
            force = _road_force_n(v[k], acc[k], x[_M], x[_A0], x[_A1], x[_B], x[_C])
            t_w = force * x[_RW]  # 2-1, all driven wheels
            driving = force >= 0
            allowed = (not driving) and v[k] >= x[_VMIN] and acc[k] >= x[_DMIN]  # rules 2-3
            if single_motor:
                p, w, room = _single_motor_step(x, v[k], t_w, driving, allowed, mp, loss)
            else:
                p, w, room = _axle_step(x, v[k], t_w, driving, allowed, two_axles, grid, fine, score, scratch, mp,
                                        loss)
            power[n, k] = p
            w_top = max(w_top, w)
            if driving:
                least = min(least, room)
        speed_max[n] = w_top
        margin[n] = least
    return power, speed_max, margin


def table(names: tuple, n: int, values: dict) -> np.ndarray:
    """The (N, len(names)) float table of the compiled loops: each named column from a scalar or
    an (N,) array, absent columns 0 (one array type, so each loop compiles once)."""
    out = np.zeros((n, len(names)))
    for k, x in values.items():
        out[:, names.index(k)] = x
    return out
