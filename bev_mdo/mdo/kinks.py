"""Kinks at an end point: where the objective or an active constraint has one-sided slopes that differ.

No gradient meets the first-order (KKT) conditions at a kink, so an end point there is "stopped before
convergence" with the kinks named: a top speed, min(motor-speed cap falling with the gear, power limit free of
it), ends an equality ``top_speed_kmh == 348.821`` where the two meet. Whether such a point is an optimum is not
claimed: one-sided slopes along each variable do not bound the slope along a kink that runs across the
variables (f = 10 |x - y| + (x + y - 4)^2 at x = y = 1.32: each variable alone raises f at 72.7, the valley x = y
lowers it at 5.5 per unit), and a check built on them said "optimum" there (a user trial).
``end_point_kinks`` steps each variable ``fd_step`` and 4 x ``fd_step`` either way (one batch) and, where none is
found, 2e-4 and 8e-4 (scaled); away from an optimum, where neither finds a kink or a failed point,
``failing_steps`` steps 1 % of each range for points where the disciplines give no value. ``one_sided_descent``
is the answers' program of a first-order step on one-sided slopes (active.py), which explains an infeasible end;
it proves nothing.
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
                    grad_max: float, at_optimum: bool = False, failed: list | None = None) -> list[dict]:
    """The kinks at ``u``: variables in which the minimised objective, an active inequality or an equality has
    one-sided slopes that differ by more than first_order.FIRST_ORDER_TOL x max(1, its largest slope) (the
    objective's: x max(1, |grad f|), ``grad_max``), by the same jump at steps h and 4h (noise shrinks the jump
    4-fold at the longer step, curvature grows it 4-fold). Each is {"in": "objective" or the constraint, "name":
    the variable, "left", "right"}, slopes per scaled unit (the objective's per objective_scale, as the check's
    gradient; a constraint's in its own unit). The steps are ``fd_step`` and 4 x that; where they find none,
    NEAR_STEP and 4 x that (a second batch), and a kink found so has "near_step": SLSQP stopped 2.4e-5 (scaled)
    short of where a top speed's motor-speed cap meets its power limit. ``at_optimum`` (a point where the
    conditions hold) looks only at the point, and asks the same jump at 16h too and a clear one (over 1e-3 x the
    largest slope): MDA noise of 1e-10 met the test at h and 4h by chance at 6 of 60 smooth optima, and a kink
    there makes the optimum unverified. ``failed``: gets the variables a step of which failed (a discipline gave
    no value a step away: the point lies at the edge of the region where the disciplines give values); away from an
    optimum, where neither pair of steps found a kink nor a failure, ``failed`` gets those of ``failing_steps`` too
    (COBYQA ended 0.0126 inside the edge, 2.5e-3 scaled, its trust region shrunk by the failed points beyond)."""
    out = _at_steps(form, u, f0, g0, h0, grad_max, form.fd_step, (1, 4, 16) if at_optimum else (1, 4), failed)
    if not at_optimum and not out and NEAR_STEP > 4 * form.fd_step:
        out = [{**k, "near_step": NEAR_STEP} for k in _at_steps(form, u, f0, g0, h0, grad_max, NEAR_STEP, (1, 4),
                                                                failed)]
    if not at_optimum and not out and failed is not None and not failed:
        failed += failing_steps(form, u)
    return out


def failing_steps(form: Formulation, u: np.ndarray, step: float = first_order.FREE_STEP) -> list[str]:
    """The variables a step of ``step`` x its range (scaled; of one scaled unit where it has none) from ``u``, either
    way within the bounds, fails in (one batch): the end lies next to a region where the disciplines give no value."""
    lo, hi = form.u_bounds
    span = np.where(np.isfinite(hi - lo), hi - lo, 1.0)
    steps = [(j, s) for j in range(form.n) for s in (step * span[j], -step * span[j]) if lo[j] <= u[j] + s <= hi[j]]
    if not steps:
        return []
    U = np.repeat(u[None, :], len(steps), axis=0)
    for i, (j, s) in enumerate(steps):
        U[i, j] += s
    X = form.to_x(U)
    f, _, _ = form.evaluate_batch(X)
    bad = form.failed_rows(X) | ~(np.abs(f) < FAIL_OBJECTIVE)
    return list(dict.fromkeys(form.var_names[j] for (j, _), b in zip(steps, bad) if b))


def _at_steps(form: Formulation, u: np.ndarray, f0: float, g0: np.ndarray, h0: np.ndarray, grad_max: float,
              h: float, multiples: tuple[int, ...], failed_out: list | None = None) -> list[dict]:
    """``end_point_kinks`` with the steps ``multiples`` x ``h`` either way (one batch)."""
    lo, hi = form.u_bounds
    n = form.n
    x0 = form.to_x(u)
    # a side is open where a variable is off its bound (as first_order.check's active bounds)
    right, left = ~_on(hi - u, hi), ~_on(u - lo, lo)
    far = multiples[-1] * h
    right, left = right & (u + far <= hi), left & (u - far >= lo)  # the steps stay in the box
    steps = [(j, sign * m * h, k) for j in range(n) for sign, side in ((1, right), (-1, left)) if side[j]
             for k, m in enumerate(multiples)]
    if not steps:
        return []
    U = np.repeat(u[None, :], len(steps), axis=0)
    for i, (j, s, _) in enumerate(steps):
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
    # slopes[k, side, r, j]: step k (multiples[k] h), side (0 right, 1 left), quantity r, variable j; NaN where closed
    slopes = np.full((len(multiples), 2, len(q0), n), np.nan)
    failed = np.zeros(n, dtype=bool)
    bad = form.failed_rows(X) | ~(np.abs(f) < FAIL_OBJECTIVE)
    for i, (j, s, k) in enumerate(steps):
        failed[j] |= bool(bad[i])
        slopes[k, int(s < 0), :, j] = (Q[i] - q0) / s
    if failed_out is not None:
        failed_out += [form.var_names[j] for j in np.flatnonzero(failed) if form.var_names[j] not in failed_out]
    g_slopes = slopes * to_g[None, None, :, None]
    refs = [max(1.0, grad_max)] + [max(1.0, float(np.nanmax(np.abs(g_slopes[0, :, r]), initial=0.0)))
                                   for r in range(1, len(q0))]
    # a kink at an optimum must be clear, 10 x the conditions' tolerance: noise near it passed the test by chance
    clear = first_order.FIRST_ORDER_TOL * (10.0 if len(multiples) > 2 else 1.0)
    out, seen = [], set()
    for r, label in enumerate(what):
        for j in range(n):
            if failed[j] or not (right[j] and left[j]) or (label, j) in seen:
                continue
            jump = g_slopes[:, 0, r, j] - g_slopes[:, 1, r, j]  # the same at every step (noise shrinks it with the
            if abs(jump[0]) > clear * refs[r] and all(  # step, curvature grows it)
                    0.5 <= jump[k + 1] / jump[k] <= 2.0 for k in range(len(multiples) - 1)):
                seen.add((label, j))  # an equality's two rows: one kink
                out.append({"in": label, "name": form.var_names[j], "left": float(slopes[0, 1, r, j]) + 0.0,
                            "right": float(slopes[0, 0, r, j]) + 0.0})  # + 0.0: no -0
    return out


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
