"""Kinks at an end point, and whether an end point at a kink is an optimum all the same.

A kink (one-sided slopes that differ) in the objective or in an active constraint leaves the first-order
(KKT) conditions unmet by any gradient: a top speed, min(motor-speed cap falling with the gear, power limit
free of it), ends an equality ``top_speed_kmh == 348.821`` at the gear where the two meet, the constrained
optimum, and the check said "stopped before convergence". ``end_point_kinks`` steps each variable ``fd_step``
and 4 x ``fd_step`` either way (one batch), names the kinks (in the objective, or in an active constraint or
equality) and, when there are some, solves ``one_sided_descent`` (active.py's answers solve it too): no step
of the scaled variables (p to the right, q to the left, none beyond a bound a variable is on) that lowers the
objective on the slopes of the side it goes to without worsening an active constraint, at step h and at 4h,
is an optimum at a kink.
"""
from __future__ import annotations

import numpy as np

from bev_mdo.mdo import first_order
from bev_mdo.mdo.formulations import FAIL_OBJECTIVE, Formulation


def _active_rows(form: Formulation, g0: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """The active inequality rows (within first_order.ACTIVE_TOL) and what each is in: its label, or for the
    two rows of a constraint whose lower bound is its upper one, ``name == bound``."""
    rows = np.flatnonzero(np.asarray(g0) >= -first_order.ACTIVE_TOL)
    spec = form.problem.constraint_rows
    equal = {n for n, k, b, _ in spec if k == "lower" and (n, "upper", b) in {(m, q, c) for m, q, c, _ in spec}}
    return rows, [f"{spec[i][0]} == {spec[i][2]:g}" if spec[i][0] in equal else form.ineq_labels[i] for i in rows]


def _on(distance: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """Within first_order.ACTIVE_TOL x max(1, |bound|) of a finite bound."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(bound) & (distance <= first_order.ACTIVE_TOL * np.maximum(1.0, np.abs(bound)))


NEAR_STEP = 2 * first_order.ACTIVE_TOL  # scaled: the second pair of steps, which sees a kink within ACTIVE_TOL


def end_point_kinks(form: Formulation, u: np.ndarray, f0: float, g0: np.ndarray, h0: np.ndarray,
                    grad_max: float) -> tuple[list[dict], dict | None]:
    """(the kinks at ``u``, the directional check at them: {"descent": the least directional derivative of the
    objective at the two steps, "tolerance", "descends": below -tolerance at either, "steps"}, None when not made
    (no kink, or a point of the stencil failed)).

    A kink: a variable in which the minimised objective, an active inequality or an equality has one-sided
    slopes that differ by more than first_order.FIRST_ORDER_TOL x max(1, its largest slope) (the objective's:
    x max(1, |grad f|), ``grad_max``), by the same jump at steps h and 4h (noise shrinks the jump 4-fold at the
    longer step, curvature grows it 4-fold). Each is {"in": "objective" or the constraint, "name": the variable,
    "left", "right"}, slopes per scaled unit (the objective's per objective_scale, as the check's gradient; a
    constraint's in its own unit). The steps are ``fd_step`` and 4 x that; where they find no kink that holds
    the point, NEAR_STEP and 4 x that (a second batch): a kink within about first_order.ACTIVE_TOL (scaled) of
    the point is at it, as a bound or a constraint that near is active (SLSQP stopped 2.4e-5 short of where a
    top speed's motor-speed cap meets its power limit, an equality's optimum)."""
    out, check = _at_steps(form, u, f0, g0, h0, grad_max, form.fd_step)
    if (check is None or check["descends"]) and NEAR_STEP > 4 * form.fd_step:
        near, near_check = _at_steps(form, u, f0, g0, h0, grad_max, NEAR_STEP)
        if near_check and not near_check["descends"] or near and not out:
            return [{**k, "near_step": NEAR_STEP} for k in near], near_check  # not at the point: within the step
    return out, check


def _at_steps(form: Formulation, u: np.ndarray, f0: float, g0: np.ndarray, h0: np.ndarray, grad_max: float,
              h: float) -> tuple[list[dict], dict | None]:
    """``end_point_kinks`` with the steps ``h`` and 4 ``h`` (one batch)."""
    lo, hi = form.u_bounds
    n = form.n
    x0 = form.to_x(u)
    # a side is open where a variable is off its bound (as first_order.check's active bounds)
    right, left = ~_on(hi - u, hi), ~_on(u - lo, lo)
    short = (right & (u + 4 * h > hi)) | (left & (u - 4 * h < lo))  # open, but the steps leave the box: no
    right, left = right & (u + 4 * h <= hi), left & (u - 4 * h >= lo)  # slope there, and no directional check
    steps = [(j, s) for j in range(n) for s, side in ((h, right), (4 * h, right), (-h, left), (-4 * h, left))
             if side[j]]
    if not steps:
        return [], None
    U = np.repeat(u[None, :], len(steps), axis=0)
    for i, (j, s) in enumerate(steps):
        U[i, j] += s
    X = form.to_x(U)
    f, _, hh = form.evaluate_batch(X)
    y = form.constraint_outputs(X)
    y0 = form.constraint_outputs(x0[None, :])[0]
    rows, labels = _active_rows(form, g0)
    # the quantities: minimised objective (per objective_scale), active constraint outputs, equalities
    Q = np.column_stack([f / form.problem.objective_scale, y[:, rows], hh])
    q0 = np.concatenate([[f0 / form.problem.objective_scale], y0[rows], h0])
    what = ["objective", *labels, *form.eq_labels]
    _, sign, scale = form.problem.g_terms()
    to_g = np.concatenate([[1.0], sign[rows] / scale[rows], np.ones(len(h0))])  # per unit of g (normalised)
    # slopes[k, side, r, j]: step k (h, 4h), side (0 right, 1 left), quantity r, variable j; NaN where closed
    slopes = np.full((2, 2, len(q0), n), np.nan)
    failed = np.zeros(n, dtype=bool)
    bad = form.failed_rows(X) | ~(np.abs(f) < FAIL_OBJECTIVE)
    for i, (j, s) in enumerate(steps):
        failed[j] |= bool(bad[i])
        slopes[int(abs(s) > 2 * h), int(s < 0), :, j] = (Q[i] - q0) / s
    g_slopes = slopes * to_g[None, None, :, None]
    refs = [max(1.0, grad_max)] + [max(1.0, float(np.nanmax(np.abs(g_slopes[0, :, r]), initial=0.0)))
                                   for r in range(1, len(q0))]
    out, seen = [], set()
    for r, label in enumerate(what):
        for j in range(n):
            if failed[j] or not (right[j] and left[j]) or (label, j) in seen:
                continue
            jump = g_slopes[:, 0, r, j] - g_slopes[:, 1, r, j]
            if abs(jump[0]) > first_order.FIRST_ORDER_TOL * refs[r] and 0.5 <= jump[1] / jump[0] <= 2.0:
                seen.add((label, j))  # an equality's two rows: one kink
                out.append({"in": label, "name": form.var_names[j], "left": float(slopes[0, 1, r, j]) + 0.0,
                            "right": float(slopes[0, 0, r, j]) + 0.0})  # + 0.0: no -0
    if not out or failed.any() or short.any():
        return out, None
    # the directional check on the normalised rows: g must not rise, an equality must not move either way
    fun = [descent(g_slopes[k], len(rows), right, left) for k in (0, 1)]
    tol = first_order.FIRST_ORDER_TOL * max(1.0, float(np.nanmax(np.abs(slopes[:, :, 0]), initial=0.0)))
    if any(v is None for v in fun):
        return out, None
    return out, {"descent": fun, "tolerance": tol, "descends": min(fun) < -tol, "steps": [h, 4 * h]}


def descent(slopes: np.ndarray, m: int, right: np.ndarray, left: np.ndarray) -> float | None:
    """The least first-order change of the objective (``slopes[side, 0]``; side 0 right, 1 left) over steps
    p - q (p, q in [0, 1] per variable, each on its side's slopes; a closed side none) that worsen none of the
    ``m`` active rows (``slopes[side, 1:1 + m]``, normalised: must not rise) and the equalities after them (must
    not move): 0 when no direction descends. A row's slope within first_order.FIRST_ORDER_TOL x max(1, the
    row's largest) is 0 (a jump that small is no kink either): finite-difference noise on a flat side (1e-9 for
    0) does not block a step. None: the program failed."""
    split = np.hstack([np.nan_to_num(slopes[0]), -np.nan_to_num(slopes[1])])  # (quantities, 2n) over (p, q)
    rows = np.vstack([split[1:1 + m], split[1 + m:], -split[1 + m:]])
    flat = np.abs(rows) <= first_order.FIRST_ORDER_TOL * np.maximum(1.0, np.abs(rows).max(axis=1, initial=0.0))[:, None]
    box = [(0.0, 1.0 if s else 0.0) for s in np.concatenate([right, left])]
    res = one_sided_descent(split[0], np.where(flat, 0.0, rows), box)
    return None if res is None else float(res.fun)


def one_sided_descent(c: np.ndarray, rows: np.ndarray, box: list[tuple[float, float]]):
    """The linear program of a first-order step at a point where slopes may differ by side: min c . (p, q)
    over p, q (each in its ``box`` entry: (0, 1), or (0, 0) for a side that is closed, a variable on its bound)
    with ``rows`` (p, q) <= 0 (each row a limit that must not get worse). The step is du = p - q: p moves each
    variable on its right-hand slope, q on its left-hand one (``c`` and ``rows`` are (right slopes, -left
    slopes)). A variable with p and q both > 0 is no step (a left slope above the right one would pay for it):
    it keeps the side it moved further to and the program is solved again. scipy's result (``fun``; ``ineqlin.marginals``), or
    None when the program fails."""
    from scipy.optimize import linprog

    n, box = len(c) // 2, list(box)
    rows = np.asarray(rows, dtype=float).reshape(-1, 2 * n)
    res = None
    for _ in range(n + 1):
        res = linprog(c, A_ub=rows if len(rows) else None, b_ub=np.zeros(len(rows)) if len(rows) else None,
                      bounds=box, method="highs")
        if res.status != 0:
            return None
        both = [j for j in range(n) if min(res.x[j], res.x[n + j]) > 1e-9]
        for j in both:
            box[n + j if res.x[j] >= res.x[n + j] else j] = (0.0, 0.0)
        if not both:
            break
    return res
