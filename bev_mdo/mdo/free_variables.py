"""Design variables an optimum does not pin: nothing the optimiser sees depends on them there.

At an optimum (the first-order conditions hold) a design variable whose objective gradient is zero, that is on
no bound and in no active constraint (their gradients in it zero too) may be held by curvature (an interior
minimum) or by nothing (y = x1 + 0 x2: any x2 is as good). The two are told apart by one batch of steps of
FREE_STEP of its range either way: where neither the objective nor any active limit moves (beyond 1e-9 of its
size: MDA noise) and the stepped points stay feasible (the run's design_check too), the optimum is not unique in
that variable, and its value is one of many. Steps ten times as long, where they stay feasible, must not move them
either: a minimum of high order ((v - 0.3)^6) is flat to 1e-9 over 1 % of the range, not over 10 %. IDF's
consistency equalities hold no variable by themselves (as MDF's analysis, they follow it): the steps, and the
optimum they are compared with, take the couplings the disciplines compute there (Jacobi sweeps until they are
consistent) and must keep them met. ``driver.end_point_check`` records them as ``first_order["free_variables"]``.
"""
from __future__ import annotations

import numpy as np

from bev_mdo.mdo import first_order
from bev_mdo.mdo.formulations import Formulation

FREE_STEP = first_order.FREE_STEP  # of the variable's range (scaled units, where it is finite; else of one scaled unit)
SAME = 1e-9       # relative change of the objective or an active limit below which it did not move
LONG = 10.0       # the longer steps, in FREE_STEPs
SWEEPS = 60       # IDF: at most this many Jacobi sweeps of the couplings (a loop contracting by 0.5 needs 30)


def consistent(form: Formulation, X: np.ndarray) -> tuple[np.ndarray, ...]:
    """(X, f, g, h) with IDF's couplings in X replaced by what the disciplines compute there, sweep after sweep
    until they agree to SAME (or SWEEPS; a failed point's NaN stops nothing); MDF's X as it is."""
    X = X.copy()
    f, g, h = form.evaluate_batch(X)
    for _ in range(SWEEPS if h.shape[1] else 0):
        if not np.nanmax(np.abs(h), initial=0.0) > SAME:
            break
        X[:, len(form.problem.names):] -= np.nan_to_num(h) * form.coupling_scale
        f, g, h = form.evaluate_batch(X)
    return X, f, g, h


def free_variables(form: Formulation, u: np.ndarray, f0: float, g0: np.ndarray,
                   grads: tuple[np.ndarray, np.ndarray, np.ndarray], fo: dict, tol: float, follows=None) -> list[dict]:
    """The design variables at the optimum ``u`` (``grads``: the check's df per objective_scale, dg, dh; ``fo``: its
    result) whose steps of FREE_STEP either way change neither the objective nor an active limit and stay feasible
    (``follows(x)``, the run's design_check, too): [{"name", "value", "step"}] (``step``: the largest, in the
    variable's unit)."""
    df, dg = grads[:2]  # (dh, IDF's consistency, holds no design variable: the steps keep it met)
    lo, hi = form.u_bounds
    rows = np.flatnonzero(np.asarray(g0) >= -first_order.ACTIVE_TOL)
    held = [dg[i] for i in rows]  # the active limits' gradients, each to its own size
    bound = {b["name"] for b in fo["active_bounds"]}
    flat = first_order.FIRST_ORDER_TOL

    def candidate(j: int) -> bool:
        return (form.var_names[j] not in bound and abs(df[j]) <= flat * max(1.0, float(np.max(np.abs(df))))
                and all(abs(r[j]) <= flat * max(1.0, float(np.max(np.abs(r)))) for r in held))
    cands = [j for j in range(len(form.problem.names)) if candidate(j)]
    steps = []  # (variable, step, long)
    for j in cands:
        span = hi[j] - lo[j] if np.isfinite(hi[j] - lo[j]) else 1.0
        steps += [(j, s, k > 1) for k in (1.0, LONG) for s in (k * FREE_STEP * span, -k * FREE_STEP * span)
                  if lo[j] <= u[j] + s <= hi[j]]
    if not steps:
        return []
    U = np.repeat(u[None, :], len(steps) + 1, axis=0)  # the optimum itself last (IDF: made consistent too)
    for i, (j, s, _) in enumerate(steps):
        U[i, j] += s
    X, f, g, h = consistent(form, form.to_x(U))
    if h.shape[1]:  # compared with the optimum as the disciplines compute it (an optimiser ends a little off)
        f0, g0 = float(f[-1]), g[-1]
    X, f, g, h = X[:-1], f[:-1], g[:-1], h[:-1]
    bad = form.failed_rows(X) | ~np.array([follows is None or follows(x) for x in X], dtype=bool)
    off = bad | (np.max(g, axis=1, initial=0.0) > tol) | (np.max(np.abs(h), axis=1, initial=0.0) > tol)
    moved = ((np.abs(f - f0) > SAME * max(abs(f0), form.problem.objective_scale))
             | (np.abs(g[:, rows] - g0[rows]) > SAME * np.maximum(1.0, np.abs(g0[rows]))).any(axis=1))
    long = np.array([t[2] for t in steps])
    moved = np.where(long, moved & ~off, moved | off)  # a long step may leave the feasible set, not move it
    x = form.to_x(u)
    out = []
    for j in cands:
        mine = [i for i, (k, _, is_long) in enumerate(steps) if k == j and not is_long]
        if mine and not moved[[i for i, t in enumerate(steps) if t[0] == j]].any():
            out.append({"name": form.var_names[j], "value": float(x[j]),
                        "step": float(max(abs(steps[i][1]) for i in mine) * form.scale[j])})
    return out
