"""First-order (KKT) check of an optimisation's end point, and the verdict that follows from it.

Pure numpy/scipy; no evaluation of its own. The caller gives the end point in the optimiser's
scaled variables u (design variables and, under IDF, couplings, each scaled to order one), the
minimised objective's gradient, the normalised inequalities g <= 0 (feasible) and equalities h = 0
with their Jacobians, all in those units.

The conditions (Nocedal & Wright, Numerical Optimization, 2nd ed., Theorem 12.1):

* stationarity: grad f + J_g^T lam + J_h^T mu - nu_lower + nu_upper = 0 over the active set,
  with lam, nu >= 0. The multipliers are estimated by bounded least squares over the active set
  (scipy.optimize.lsq_linear); the residual is the **projected gradient of the Lagrangian** and its
  largest component, relative to max(1, |grad f|), must be within ``tol``;
* primal feasibility: the largest violation of g and |h| within the run's feasibility tolerance;
* complementarity: max |lam_i g_i| and |nu_j (distance to bound j)| within ``tol``
  (an inequality or bound counts as active within ``active_tol`` of its limit);
* every derivative known: a variable whose finite-difference points failed (``unknown``: the
  gradient has a 0 there that no model gave) leaves the conditions unverified, whatever the numbers.

Verdicts (in this order): ``infeasible`` (violation above the feasibility tolerance, or the point
failed), ``optimum`` (the conditions hold), ``no progress from the start point`` (the end point is
the start point), ``stopped before convergence`` (anything else).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.optimize import lsq_linear

FIRST_ORDER_TOL = 1e-4   # relative stationarity and complementarity that count as "the conditions hold"
ACTIVE_TOL = 1e-4        # an inequality (normalised) or a bound (scaled units) this close to its limit is active
FREE_STEP = 0.01         # free_variables.py's steps, of a variable's range (else of one scaled unit)

OPTIMUM = "optimum"
STOPPED = "stopped before convergence"
NO_PROGRESS = "no progress from the start point"
INFEASIBLE = "infeasible"


def bound_violation(u: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> float:
    """How far ``u`` lies outside [lower, upper], in the units of ``active_tol`` (scaled, over
    max(1, |bound|)); 0 inside. An optimiser may step there (trust-constr, COBYLA), but such a point
    is not feasible."""
    u, lower, upper = (np.asarray(a, dtype=float) for a in (u, lower, upper))
    with np.errstate(invalid="ignore"):  # an infinite bound: inf / inf, dropped below
        out = np.concatenate([(lower - u) / np.maximum(1.0, np.abs(lower)), (u - upper) / np.maximum(1.0, np.abs(upper))])
    return float(np.max(out[np.isfinite(out)], initial=0.0))


def check(u: np.ndarray, lower: np.ndarray, upper: np.ndarray, grad_f: np.ndarray, g: np.ndarray,
          jac_g: np.ndarray, h: np.ndarray, jac_h: np.ndarray, *, names: Sequence[str],
          ineq_labels: Sequence[str], eq_labels: Sequence[str], feasibility_tol: float,
          tol: float = FIRST_ORDER_TOL, active_tol: float = ACTIVE_TOL, point_ok: bool = True,
          moved: bool = True, unknown: Sequence[str] = ()) -> dict:
    """The first-order numbers and the verdict at ``u`` (JSON-ready dict; see the module doc).

    ``lower``/``upper``: bounds of u (may be infinite); ``g`` (m,), ``jac_g`` (m, n), ``h`` (p,),
    ``jac_h`` (p, n); ``moved``: False when the end point is the start point; ``unknown``: the
    variables without a derivative there (their finite-difference points failed)."""
    u, lower, upper, grad_f = (np.asarray(a, dtype=float) for a in (u, lower, upper, grad_f))
    n = len(u)
    g, h = np.asarray(g, dtype=float).reshape(-1), np.asarray(h, dtype=float).reshape(-1)
    jac_g, jac_h = np.asarray(jac_g, dtype=float).reshape(len(g), n), np.asarray(jac_h, dtype=float).reshape(len(h), n)
    violation = max(float(np.max(g, initial=0.0)), float(np.max(np.abs(h), initial=0.0)),
                    bound_violation(u, lower, upper))
    to_lower, to_upper = u - lower, upper - u
    act_g = np.flatnonzero(g >= -active_tol)
    act_lo = np.flatnonzero(np.isfinite(lower) & (to_lower <= active_tol * np.maximum(1.0, np.abs(lower))))
    act_hi = np.flatnonzero(np.isfinite(upper) & (to_upper <= active_tol * np.maximum(1.0, np.abs(upper))))
    act_hi = np.setdiff1d(act_hi, act_lo)  # a degenerate box: one side
    cols = ([jac_g[i] for i in act_g] + [jac_h[k] for k in range(len(h))]
            + [-np.eye(n)[j] for j in act_lo] + [np.eye(n)[j] for j in act_hi])
    nonneg = [True] * len(act_g) + [False] * len(h) + [True] * (len(act_lo) + len(act_hi))
    dependent = False  # the active gradients linearly dependent: the multipliers are one split of many
    if cols:
        A = np.column_stack(cols)
        tol_a = 1e-8 * max(1.0, float(np.max(np.abs(A))))  # an equality's two rows (<= and >=) count once
        single = [i for i in range(A.shape[1]) if not any(np.allclose(A[:, i], -A[:, j], rtol=1e-8, atol=tol_a)
                                                          for j in range(i))]
        dependent = bool(np.linalg.matrix_rank(A[:, single], tol=tol_a) < len(single))
        lb = np.where(nonneg, 0.0, -np.inf)
        sol = lsq_linear(A, -grad_f, bounds=(lb, np.full(len(cols), np.inf)), method="bvls").x
        residual = grad_f + A @ sol
    else:
        sol, residual = np.zeros(0), grad_f.copy()
    ref = max(1.0, float(np.max(np.abs(grad_f), initial=0.0)))
    stationarity = float(np.max(np.abs(residual), initial=0.0)) / ref
    lam = sol[:len(act_g)]
    mu = sol[len(act_g):len(act_g) + len(h)]
    nu = sol[len(act_g) + len(h):]
    gaps = np.concatenate([np.abs(lam * g[act_g]), np.abs(nu[:len(act_lo)] * to_lower[act_lo]),
                           np.abs(nu[len(act_lo):] * to_upper[act_hi])])
    complementarity = float(np.max(gaps, initial=0.0)) / ref
    holds = bool(stationarity <= tol and complementarity <= tol and not unknown)
    if not point_ok or not violation <= feasibility_tol:
        verdict = INFEASIBLE
    elif holds:
        verdict = OPTIMUM
    elif not moved:
        verdict = NO_PROGRESS
    else:
        verdict = STOPPED
    return {
        "verdict": verdict,
        "point_failed": not point_ok,
        "moved": bool(moved),
        "conditions_hold": holds,
        "stationarity": stationarity,
        "complementarity": complementarity,
        "max_violation": violation,
        "tolerance": tol,
        "feasibility_tolerance": feasibility_tol,
        "active_tolerance": active_tol,
        "gradient_norm": float(np.max(np.abs(grad_f), initial=0.0)),
        "unknown_derivatives": list(unknown),
        **({"dependent_active": True} if dependent else {}),
        "active_constraints": [{"name": ineq_labels[i], "value": float(g[i]), "multiplier": float(v)}
                               for i, v in zip(act_g, lam)],
        "equalities": [{"name": eq_labels[k], "value": float(h[k]), "multiplier": float(v)}
                       for k, v in enumerate(mu)],
        "active_bounds": ([{"name": names[j], "kind": "lower", "multiplier": float(v)}
                           for j, v in zip(act_lo, nu[:len(act_lo)])]
                          + [{"name": names[j], "kind": "upper", "multiplier": float(v)}
                             for j, v in zip(act_hi, nu[len(act_lo):])]),
    }


def verdict_line(fo: dict) -> str:
    """One line for the terminal, e.g. 'optimum (first-order conditions hold to 3.1e-09)'."""
    v = fo["verdict"]
    worst = max(fo["stationarity"], fo["complementarity"])
    if v == OPTIMUM:
        still = ("; the start point, where the gradient is about zero: a saddle or a flat region passes this "
                 "check too, try --starts N" if not fo.get("moved", True) and fo["gradient_norm"] <= fo["tolerance"]
                 and not fo["active_constraints"] and not fo["active_bounds"] and not fo["equalities"] else "")
        return f"optimum (first-order conditions hold to {worst:.2g}; tolerance {fo['tolerance']:g}{still})"
    if v == INFEASIBLE and fo.get("cannot_follow"):  # driver: RunSettings.design_check (its motor cannot follow the cycle)
        return f"infeasible ({'; '.join(fo['cannot_follow'])})"
    if v == INFEASIBLE and fo.get("point_failed"):  # failure: the driver's, when the final analysis failed
        return f"infeasible (the point failed: {fo.get('failure') or 'the disciplines gave no value there'})"
    if v == INFEASIBLE:
        return (f"infeasible (largest violation {fo['max_violation']:.3g} > feasibility tolerance "
                f"{fo['feasibility_tolerance']:g})")
    if (d := fo.get("derivatives_disagree")):  # driver.end_point_check: analytic partials against finite differences
        return (f"{v} (the first-order conditions hold with the disciplines' analytic derivatives but not with finite "
                f"differences: d {d['of']} / d {d['wrt']} is {d['analytic']:.5g} analytic, {d['fd']:.5g} by finite "
                "differences (scaled units); bev-mdo check-partials names the partial)")
    unknown = fo.get("unknown_derivatives")
    if unknown:
        return (f"{v} (no derivative in {', '.join(unknown)}: {'its' if len(unknown) == 1 else 'their'} "
                f"finite-difference points failed, "
                "so the first-order conditions cannot be verified)")
    kinks = fo.get("kinks")  # mdo/kinks.py: one-sided slopes of the objective or an active constraint differ
    kink = f"; {_kinks(kinks)}: a nonsmooth model, whose optimum the first-order conditions cannot verify" if kinks else ""
    if fo.get("kink_at_optimum"):  # driver.end_point_check: the conditions held on a gradient across a kink
        kink += "; the numbers above hold on a gradient taken across the kink, which does not verify it"
    scale = (f"; the optimiser sees an objective of {fo['objective_seen']:.1e}: give problem.objective_scale about "
             f"{fo['objective_seen']:.0e} so that it is of order one") if fo.get("objective_seen") else ""
    return (f"{v} (projected gradient of the Lagrangian {fo['stationarity']:.3g}, complementarity "
            f"{fo['complementarity']:.3g}; tolerance {fo['tolerance']:g}{kink}{scale})")


def _kinks(kinks: Sequence[dict]) -> str:
    """mdo/kinks.py's kinks by what they are in (the objective, or a constraint), each with its variables and
    their one-sided slopes, e.g. 'the objective has a kink at the point in x (slope 4 on its left, 6 on its right, per scaled unit)' (found
    with the longer steps: 'within 0.0002 (scaled) of the point')."""
    by: dict[str, list[dict]] = {}
    for k in kinks:
        by.setdefault(k.get("in", "objective"), []).append(k)
    parts = []
    for what, ks in by.items():
        where = f"within {ks[0]['near_step']:g} (scaled) of the point" if ks[0].get("near_step") else "at the point"
        parts.append(f"{'the objective' if what == 'objective' else what} has a kink {where} in " + ", ".join(
            f"{k['name']} (slope {k['left']:.5g} on its left, {k['right']:.5g} on its right, per scaled unit)"
            for k in ks))
    return "; ".join(parts)


def note_lines(fo: dict, optimizer: str = "the optimiser", converged: bool = False, ended: dict | None = None
               ) -> list[str]:
    """What the verdict line does not say, a line each: the design variables an optimum does not pin
    (driver.end_point_check's ``free_variables``), and where ``optimizer`` said it ``converged`` but the conditions
    do not hold (no kink, no unknown or disagreeing derivative to explain it), what to check; ``ended``: the
    record of the optimiser's last iterate where the result is an earlier one (then the reason is there). A step
    from the end point that failed (driver.end_point_check's ``failed_steps``) is the likelier cause."""
    lines = [_free_line(fo["free_variables"])] if fo.get("free_variables") else []
    if fo.get("dependent_active"):  # e.g. a constraint and its copy: raising one limit alone may change nothing
        lines.append("the gradients of the active constraints and bounds are linearly dependent: their multipliers "
                     "are not unique (those below are one split of many), nor is the change per limit raised alone")
    if fo.get("failed_points"):  # driver: points of the run that gave no value (the optimiser's, the check's)
        lines.append(f"{fo['failed_points']} point(s) of the run gave no value; the first: {fo['first_failure']}")
    if fo.get("outside_coupling_bounds"):  # driver: an MDF result beyond problem.coupling_bounds
        lines.append(_coupling_bounds_line(fo["outside_coupling_bounds"]))
    if converged and ended is not None and fo["verdict"] != OPTIMUM:  # its end point is not what was judged
        why = ("cannot follow the drive cycle, a check the optimiser does not see (constrain the energy "
               "discipline's margins so that it does: options {feasibility_outputs: true}, and its margins >= 0: "
               "drive_force_margin_n (flat), drive_torque_margin_nm (chain, quasi_static); docs/user-problems.md)"
               if ended.get("cannot_follow") else "is infeasible" if not ended.get("feasible") else "is worse")
        lines.append(f"{optimizer} says it converged, at iteration {ended.get('iteration')}, which {why}: the result "
                     "is an earlier point, where the first-order conditions need not hold")
    elif converged and fo["verdict"] == STOPPED and fo.get("failed_steps") and not fo.get("derivatives_disagree"):
        lines.append(f"{optimizer} says it converged, but the first-order conditions do not hold at its end point, and "
                     f"a small step from it in {', '.join(fo['failed_steps'])} fails (discipline_errors): it lies at the "
                     "edge of the region where the disciplines give values, which the optimiser cannot step past; "
                     "bounds inside that region would make it a limit the check can judge")
    elif converged and fo["verdict"] == STOPPED and not (fo.get("kinks") or fo.get("unknown_derivatives")
                                                         or fo.get("derivatives_disagree")):
        from bev_mdo.mdo.optimizers import GRADIENT_BASED

        head = f"{optimizer} says it converged, but the first-order conditions do not hold at its end point "
        if optimizer in GRADIENT_BASED or optimizer == "the optimiser":
            lines.append(head + ("(judged on the gradient assembled from the disciplines' analytic partials, the "
                                 "optimiser's own, so a wrong partial misleads both): a wrong derivative is a common "
                                 "cause; bev-mdo check-partials CONFIG compares each discipline's partials with finite "
                                 "differences, bev-mdo check-totals CONFIG the totals"
                                 if fo.get("derivatives") == "analytic" else
                                 # no analytic partial in the run: its own stopping rule, or the differences' step
                                 "(judged on finite differences of the whole analysis, optimizer.fd_step, as the "
                                 "optimiser's): its stopping tolerance (optimizer.options, e.g. ftol) may be too loose "
                                 "for the problem, or the step too coarse for it"))
        else:  # a derivative-free optimiser: the check's gradient is not its own; a wrong partial misleads the check
            analytic = fo.get("derivatives") == "analytic"
            on = ("the gradient assembled from the disciplines' analytic partials" if analytic
                  else "finite differences of the whole analysis (optimizer.fd_step)")
            idf = ("; under IDF its every step must also keep the consistency equalities met, which a search on values "
                   "alone does poorly (--formulation mdf meets them by the MDA)" if fo.get("equalities") else "")
            lines.append(head + f"(judged on {on}, which {optimizer}, derivative-free, does not use): its own stopping "
                         f"rule (optimizer.options) ended it where that gradient still descends{idf}; a gradient-based "
                         "optimiser (--optimizer SLSQP) can go on from there"
                         + (" (a wrong partial would mislead the check alone: bev-mdo check-partials CONFIG rules it "
                            "out)" if analytic else ""))
    return lines


def _coupling_bounds_line(outside: list[dict]) -> str:
    """The note of an MDF result's couplings beyond ``problem.coupling_bounds``, one line."""
    first = outside[0]
    side = {"lower": "below its lower", "upper": "above its upper"}
    names = ", ".join(f"{b['name']} = {b['value']:.6g} is {side[b['kind']]} bound {b['bound']:g}" for b in outside)
    op = ">=" if first["kind"] == "lower" else "<="
    return (f"{names} of problem.coupling_bounds: those bounds hold IDF's coupling variables; MDF, whose MDA sets the "
            f"couplings, does not apply them, so the two formulations solve different problems here; a limit both "
            f"keep is a constraint (problem.constraints, or --constraint \"{first['name']}{op}{first['bound']:g}\")")


def _free_line(free: list[dict]) -> str:
    """The note of ``free_variables``' variables, one line."""
    names = ", ".join(f"{v['name']} = {v['value']:.6g}" for v in free)
    one = len(free) == 1
    return (f"the objective's gradient is zero in {names} at the optimum, and {'it is' if one else 'they are'} "
            f"neither on a bound nor in an active constraint (a step of {FREE_STEP:g} of {'its' if one else 'each'} "
            "range either way changes neither the objective nor an active limit, and stays feasible; nor do steps ten "
            "times as long where they stay feasible): the optimum is "
            f"not unique in {'it' if one else 'them'} ({'its value is' if one else 'their values are'} arbitrary "
            "where the design stays feasible)")


def limit_rates(fo: dict, problem, var_names: Sequence[str], var_scale: Sequence[float],
                bounds: tuple[Sequence[float], Sequence[float]] | None = None) -> None:
    """Each active constraint row and bound of ``fo`` gets ``d_objective_d_limit``: how the optimum's objective
    moves, in its own unit, per unit its limit (or bound) is raised, from the multiplier (envelope theorem,
    Nocedal & Wright eq 12.84): the multipliers are per unit of the scaled objective (f / objective_scale, -f to
    maximise) and of the normalised constraint g = sign (y - b) / scale or scaled variable (x - lower) / scale.
    A bound also gets its ``bound`` (physical; ``bounds``: the variables' (lower, upper))."""
    _, sign, scale = problem.g_terms()
    row = {label: i for i, label in enumerate(problem.constraint_labels)}
    sense = (-1.0 if problem.maximize else 1.0) * problem.objective_scale
    for c in fo["active_constraints"]:
        if (i := row.get(c["name"])) is not None:
            c["d_objective_d_limit"] = float(-sense * c["multiplier"] * sign[i] / scale[i]) + 0.0  # + 0.0: no -0
    where = dict(zip(var_names, np.asarray(var_scale, dtype=float)))
    limits = {k: dict(zip(var_names, map(float, v))) for k, v in zip(("lower", "upper"), bounds or ((), ()))}
    for b in fo["active_bounds"]:
        if b["name"] in limits.get(b["kind"], {}):
            b["bound"] = limits[b["kind"]][b["name"]]
        if b["name"] in where:
            b["d_objective_d_limit"] = float(sense * b["multiplier"] * (1.0 if b["kind"] == "lower" else -1.0)
                                             / where[b["name"]]) + 0.0


def exit_status(doc: dict, fixed_budget: bool = False) -> int:
    """bev-mdo optimize's exit status of a run document (``RunResult.to_dict()`` and what the run adds), a
    hand-started coordinator_node's too: 0 an optimum (or, with ``fixed_budget``, any feasible end);
    1 infeasible; 3 the recorder failed; 4 a discipline stopped answering (before 1: a node killed while the start
    point was evaluated left every point failed, and a script keyed on the status read it as an infeasible design);
    5 feasible but not a verified optimum."""
    if doc.get("recorder_failed"):
        return 3
    if doc.get("unresponsive_disciplines"):
        return 4
    if not doc["feasible"]:
        return 1
    return 0 if doc["verdict"] == OPTIMUM or fixed_budget else 5
