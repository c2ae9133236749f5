"""Design variables an optimum does not pin: nothing the optimiser sees depends on them there.

At an optimum (the first-order conditions hold) a design variable whose objective gradient is zero, that is on
no bound and in no active constraint (their gradients in it zero too) may be held by curvature (an interior
minimum) or by nothing (y = x1 + 0 x2: any x2 is as good). The two are told apart by one batch of steps of
FREE_STEP of its range either way: where neither the objective nor any active limit moves (beyond 1e-9 of its
size: MDA noise) and the stepped points stay feasible (the run's design_check too), the optimum is not unique in
that variable, and its value is one of many. IDF's consistency equalities hold no variable by themselves (as
MDF's analysis, they follow it): the steps take the couplings the disciplines compute there (a sweep per
coupling) and must keep them met. ``driver.end_point_check`` records them as ``first_order["free_variables"]``.
"""
from __future__ import annotations

import numpy as np

from bev_mdo.mdo import first_order
from bev_mdo.mdo.formulations import Formulation

FREE_STEP = first_order.FREE_STEP  # of the variable's range (scaled units, where it is finite; else of one scaled unit)
SAME = 1e-9       # relative change of the objective or an active limit below which it did not move


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
    steps = []
    for j in cands:
        span = hi[j] - lo[j] if np.isfinite(hi[j] - lo[j]) else 1.0
        d = FREE_STEP * span
        steps += [(j, s) for s in (d, -d) if lo[j] <= u[j] + s <= hi[j]]
    if not steps:
        return []
    U = np.repeat(u[None, :], len(steps), axis=0)
    for i, (j, s) in enumerate(steps):
        U[i, j] += s
    X = form.to_x(U)
    f, g, h = form.evaluate_batch(X)
    for _ in range(h.shape[1]):  # IDF: the couplings as the disciplines compute them at the steps
        X[:, len(form.problem.names):] -= h * form.coupling_scale
        f, g, h = form.evaluate_batch(X)
    bad = form.failed_rows(X) | ~np.array([follows is None or follows(x) for x in X], dtype=bool)
    moved = ((np.abs(f - f0) > SAME * max(abs(f0), form.problem.objective_scale))
             | (np.abs(g[:, rows] - g0[rows]) > SAME * np.maximum(1.0, np.abs(g0[rows]))).any(axis=1)
             | (np.max(g, axis=1, initial=0.0) > tol) | (np.max(np.abs(h), axis=1, initial=0.0) > tol) | bad)
    x = form.to_x(u)
    out = []
    for j in cands:
        mine = [i for i, (k, _) in enumerate(steps) if k == j]
        if mine and not moved[mine].any():
            out.append({"name": form.var_names[j], "value": float(x[j]),
                        "step": float(max(abs(steps[i][1]) for i in mine) * form.scale[j])})
    return out
