"""Compiled battery loops (numba) of the quasi-static and topology models: the battery stepped over
a design's precomputed demand (compiled.py), as ``quasi_static.integrate_energy`` /
``integrate_range`` do (eqs 2-9..2-17, rule 4, the 2C cap), to 1e-12 of them.

* Range steps the battery over the range cycle's demand, cycle after cycle, and stops each design
  at its own crossing of ``final_soc``; steps with zero demand leave the battery as it is (no
  current, no energy) and are skipped.
* ``_LANES`` designs are stepped side by side without branches, in SIMD registers: one design's
  SOC recurrence is a chain of dependent divisions and a square root that leaves the core waiting.
  Each lane keeps its SOC interval of the cell's tables and looks it up again only when the SOC
  leaves it. Range runs the designs in the order of their estimated range, so the lanes of a block
  stop together. Each lane's steps are its own design's: results do not depend on the batch.
"""
from __future__ import annotations

import math

import numpy as np
import numba
from numba import prange

from .compiled import _jit

# columns of the per-design battery table ``cols`` (N, len(BATTERY_COLUMNS)) of the battery loops
BATTERY_COLUMNS = ("cells_series", "cells_parallel", "capacity_c", "charge_current_max_a", "regen_max_soc",
                   "initial_soc", "discharge_current_max_a", "loss_weight", "final_soc")
_NS, _NP, _QC, _ICHG, _SOCMAX, _SOC0, _IDIS, _WLOSS, _SOCSTOP = range(9)
_LANES = 16  # designs stepped side by side, as SIMD lanes: one design's SOC recurrence is a chain of
# dependent divisions and a square root that leaves the core waiting. The lane loops have no branches
# and read and write one state array (``st``), so the compiler puts the lanes in vector registers
# rows of ``st``: the lane's SOC interval (``_settle``: its ends, its start and the three tables'
# value there and slope; np.interp is slope (x - xp[j]) + fp[j], outside the grid slope 0 at the end
# value), its SOC, the new SOC, and the sums and extremes of ``_battery``'s outputs
_LO, _HI, _X0, _OCV, _S_OCV, _RD, _S_RD, _RC, _S_RC, _SOC, _NEW, _E, _REGEN, _LOW, _ROOM_W, _ROOM_I = range(16)


@_jit(inline="always")
def _settle(soc, lane, st, cell):
    """Put lane ``lane``'s SOC interval (``st``, rows ``_LO``..) on the one that holds ``soc``, as
    np.interp finds it: the largest j with xp[j] <= soc, clamped at both ends of the grid."""
    xp = cell[0]
    n = xp.shape[0]
    if soc >= xp[n - 1] or soc < xp[0]:
        j = n - 1 if soc >= xp[n - 1] else 0
        st[_LO, lane], st[_HI, lane] = (xp[n - 1], np.inf) if j else (-np.inf, xp[0])
        for row, fp in ((_OCV, cell[1]), (_RD, cell[2]), (_RC, cell[3])):
            st[row, lane], st[row + 1, lane] = fp[j], 0.0
    else:
        j = 0
        while j < n - 2 and xp[j + 1] <= soc:
            j += 1
        st[_LO, lane], st[_HI, lane] = xp[j], xp[j + 1]
        for row, fp, slopes in ((_OCV, cell[1], cell[4]), (_RD, cell[2], cell[5]), (_RC, cell[3], cell[6])):
            st[row, lane], st[row + 1, lane] = fp[j], slopes[j]
    st[_X0, lane] = xp[j]


@_jit(inline="always")
def _step(demand_w, dt, x, st, g):
    """One battery step (``quasi_static._Battery.step``) of lane ``g`` (constants ``x``, rows of
    ``BATTERY_COLUMNS``; SOC and its interval ``st``): terminal power, current, resistance,
    ocv^2/4R minus the drive demand (W, < 0: not delivered), and the new SOC (2-9..2-15, rule 4,
    2C cap). No branches: every value is read first, then selected (a read under a condition keeps
    the compiler from vectorising). Zero demand leaves SOC and energy exactly as they were."""
    soc, ns, i_chg, soc_max = st[_SOC, g], x[_NS, g], x[_ICHG, g], x[_SOCMAX, g]
    p_drive = max(demand_w, 0.0)
    p_regen = demand_w if (demand_w < 0) & (soc <= soc_max) else 0.0  # rule 4: none above 90 % SOC
    ds = soc - st[_X0, g]
    voc = ns * (st[_S_OCV, g] * ds + st[_OCV, g])
    r_charge, r_discharge = st[_S_RC, g] * ds + st[_RC, g], st[_S_RD, g] * ds + st[_RD, g]
    r = ns * (r_charge if p_regen < 0 else r_discharge) / x[_NP, g]
    p_chg_lim = (voc - (-i_chg) * r) * (-i_chg)  # 2-12 at the 2C charge cap
    p_max = voc * voc / (4.0 * r)
    power = min(p_drive, p_max) + max(p_regen, p_chg_lim)
    v_bt = 0.5 * (voc + math.sqrt(max(voc * voc - 4.0 * power * r, 0.0)))  # 2-13, 2-14
    i = power / v_bt  # 2-11
    return power, i, r, p_max - p_drive, soc - i * dt / x[_QC, g]  # 2-9, 2-10


@_jit(parallel=True)
def _battery(demand_w, step_pair, dt, step_m, max_repeats, cols, cell, to_range, lanes):
    """The battery stepped over each design's demand (step k's in column ``step_pair[k]``): once
    from ``initial_soc`` (energy), or from 100 % SOC repeating the cycle until ``final_soc``
    (``to_range``). One kernel for both (compile time). Returns energy drawn and returned (J), final
    SOC, the lowest SOC, the least ocv^2/4R minus drive demand (W) and the least 1 - current /
    discharge limit over the drawing steps (both inf without one), and the distance (m, inf if not
    reached). Designs run ``_LANES`` at a time; each lane's steps are its own design's (a lane
    past its crossing, or without a design, steps on unread). ``lanes`` = ``_LANES``: the lane
    loops that step run to it, a number the compiler does not know, so that it vectorises them
    instead of unrolling them; the arrays' rows are ``_LANES`` long, a length it knows, so that it
    sees the rows do not overlap."""
    n_pts, n_steps, n_pairs = demand_w.shape[0], step_pair.shape[0], demand_w.shape[1]
    energy = np.zeros(n_pts)
    regen = np.zeros(n_pts)
    soc_end = np.empty(n_pts)
    soc_low = np.empty(n_pts)
    power_room = np.full(n_pts, np.inf)
    current_room = np.full(n_pts, np.inf)
    out = np.full(n_pts, np.inf)
    for block in prange((n_pts + _LANES - 1) // _LANES):
        n0 = block * _LANES
        size = min(_LANES, n_pts - n0)
        d_tab = np.zeros((n_pairs, _LANES))  # the _LANES' demand side by side (no design: 0)
        x = np.empty((cols.shape[1], _LANES))
        st = np.zeros((16, _LANES))
        active = np.zeros(_LANES, np.bool_)
        for g in range(_LANES):
            n = n0 + min(g, size - 1)  # an empty lane copies the last design's constants (stays finite)
            for c in range(cols.shape[1]):
                x[c, g] = cols[n, c]
            if g < size:
                for u in range(n_pairs):
                    d_tab[u, g] = demand_w[n, u]
            st[_SOC, g] = st[_LOW, g] = 1.0 if to_range else x[_SOC0, g]
            st[_ROOM_W, g] = st[_ROOM_I, g] = np.inf
            active[g] = g < size
            _settle(st[_SOC, g], g, st, cell)
        left = size
        travelled = 0.0
        for _ in range(max_repeats if to_range else 1):
            for k in range(n_steps):
                d = d_tab[step_pair[k]]
                moving = False
                for g in range(_LANES):
                    moving |= d[g] != 0.0
                if moving:  # a step without demand: no current, no energy, SOC unchanged
                    dtk = dt[k]
                    if to_range:
                        for g in range(lanes):
                            st[_NEW, g] = _step(d[g], dtk, x, st, g)[4]
                    else:
                        for g in range(lanes):
                            power, i, r, room, new = _step(d[g], dtk, x, st, g)
                            drawing, room_w, room_i, room_now = d[g] > 0.0, st[_ROOM_W, g], st[_ROOM_I, g], 1.0 - i / x[_IDIS, g]
                            st[_ROOM_W, g] = min(room_w, room) if drawing else room_w
                            st[_ROOM_I, g] = min(room_i, room_now) if drawing else room_i
                            st[_LOW, g] = min(st[_LOW, g], new)
                            st[_E, g] += (power + x[_WLOSS, g] * i * i * r) * dtk  # 2-16, 2-17
                            st[_REGEN, g] -= min(power, 0.0) * dtk
                            st[_NEW, g] = new
                    for g in range(_LANES):
                        soc, new = st[_SOC, g], st[_NEW, g]
                        if to_range and active[g] and new <= x[_SOCSTOP, g]:  # the crossing, inside its step
                            out[n0 + g] = travelled + (soc - x[_SOCSTOP, g]) / max(soc - new, 1e-300) * step_m[k]
                            active[g] = False
                            left -= 1
                        if not (st[_LO, g] <= new < st[_HI, g]):
                            _settle(new, g, st, cell)
                        st[_SOC, g] = new
                travelled += step_m[k]
                if left == 0:
                    break
            if left == 0:
                break
        for g in range(size):
            n = n0 + g
            soc_end[n], soc_low[n], energy[n], regen[n] = st[_SOC, g], st[_LOW, g], st[_E, g], st[_REGEN, g]
            power_room[n], current_room[n] = st[_ROOM_W, g], st[_ROOM_I, g]
    return energy, regen, soc_end, soc_low, power_room, current_room, out


def battery_energy(demand_w, step_pair, dt, cols, cell) -> tuple:
    """Step each design's battery over its demand from ``initial_soc``
    (``quasi_static.integrate_energy``): energy drawn and returned (J, 2-16, 2-17), final SOC,
    the lowest SOC over the cycle, the least ocv^2/4R minus drive demand (W) and the least
    1 - current / discharge limit (both inf if the cycle never draws; the flags are these >= 0)."""
    with numba.parallel_chunksize(1):
        return _battery(demand_w, step_pair, dt, np.zeros(dt.shape[0]), 1, cols, cell, False, _LANES)[:6]


def battery_range_m(demand_w, step_pair, dt, step_m, max_repeats: int, cols, cell) -> np.ndarray:
    """Distance (m) from 100 % SOC to ``final_soc`` repeating the cycle's demand
    (``quasi_static.integrate_range``), the crossing interpolated inside its step; inf if the
    battery is still above after ``max_repeats`` cycles. The designs run in the order of their
    charge over net demand per cycle, so that the ``_LANES`` stepped together stop together (in
    random order a block steps 1.2 times its designs' steps, to its longest range)."""
    per_cycle = demand_w @ np.bincount(step_pair, weights=dt, minlength=demand_w.shape[1])  # J, net
    order = np.argsort(cols[:, _QC] * cols[:, _NS] / np.maximum(per_cycle, 1e-300), kind="stable")
    out = np.empty(cols.shape[0])
    with numba.parallel_chunksize(1):
        out[order] = _battery(demand_w[order], step_pair, dt, step_m, int(max_repeats), cols[order], cell, True,
                              _LANES)[6]
    return out


def cell_tables(soc, ocv_v, r_discharge_ohm, r_charge_ohm) -> tuple:
    """A cell's tables as the battery loops take them (``_step``'s ``cell``)."""
    tabs = tuple(np.array(x, dtype=float) for x in (soc, ocv_v, r_discharge_ohm, r_charge_ohm))
    return (*tabs, *(np.diff(y) / np.diff(tabs[0]) for y in tabs[1:]))
