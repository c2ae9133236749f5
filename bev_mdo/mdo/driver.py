"""Run an optimisation, or evaluate one design, from a resolved config and any evaluator.

The same functions run in-process (``InProcessEvaluator``) and over ROS (the
lead's ROS evaluator); only the evaluator differs.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import OptimizeResult

from bev_mdo.mdo import first_order
from bev_mdo.mdo.evaluator import DisciplinesLost, Evaluator
from bev_mdo.mdo.formulations import FORMULATIONS, Formulation
from bev_mdo.mdo.free_variables import free_variables
from bev_mdo.mdo.kinks import end_point_kinks
from bev_mdo.mdo.mda import MDA
from bev_mdo.mdo.optimizers import (GRADIENT_BASED, NOISE_VIOLATION, canonical_name, check_fit,
                                    run_optimizer)
from bev_mdo.mdo.problem import Problem
from bev_mdo.mdo.settings import FEASIBILITY_TOL, RunSettings

RESTARTS = 1  # derivative-free runs that claim convergence where the first-order check fails
RESTARTABLE = frozenset({"COBYQA", "COBYLA"})
BUDGET_OPTIONS = frozenset({"maxiter", "maxfev"})  # a budget the user set is not overridden by a restart
BEST_REL_TOL = 1e-6  # an earlier feasible iterate replaces the last one only if better by more than this


Run = RunSettings | Mapping[str, Any]  # typed settings (config.run_settings), or a resolved config


def pick_result(history: list[dict], sign: float, converged: bool, tol: float = FEASIBILITY_TOL) -> int:
    """Which iteration record is the run's result: the optimiser's last iterate, unless it is
    infeasible or an earlier feasible record is better by more than BEST_REL_TOL (relative; within
    that, the last iterate, which has converged further, is kept). When the optimiser reports
    convergence at a feasible last iterate, an earlier record must also be no more violated than it
    (up to NOISE_VIOLATION x ``tol``): a point inside the feasibility tolerance buys objective with its
    violation, so it does not displace the converged optimum. With no feasible record, the last
    one (the run is then infeasible). ``sign``: +1 minimise, -1 maximise."""
    k = len(history) - 1
    feasible = [i for i, r in enumerate(history) if r["feasible"]]
    if not feasible:
        return k
    last = history[k]
    if last["feasible"] and converged:
        noise = NOISE_VIOLATION * tol
        feasible = [i for i in feasible if history[i]["max_violation"] <= last["max_violation"] + noise]
    best = min(feasible, key=lambda i: (sign * history[i]["objective"], -i))
    f_last, f_best = sign * last["objective"], sign * history[best]["objective"]
    if not last["feasible"] or f_best < f_last - BEST_REL_TOL * max(abs(f_last), 1.0):
        return best
    return k


def feasibility_tolerance(run: Run) -> float:
    """The run's ``optimizer.feasibility_tolerance`` (mdo/settings.py: FEASIBILITY_TOL by default)."""
    return float(RunSettings.of(run).optimizer.feasibility_tolerance)


@dataclass
class RunResult:
    """Outcome of ``run_optimization`` (``to_dict()`` is JSON-ready)."""

    formulation: str
    optimizer: str
    success: bool                     # the first-order check verified an optimum (verdict == "optimum")
    message: str                      # the optimiser's own message
    design: dict[str, float]
    objective_name: str
    objective: float
    outputs: dict[str, float]
    constraints: dict[str, dict]
    max_violation: float
    feasible: bool
    iterations: int
    mda_evaluations: int
    discipline_evaluations: dict[str, int]
    points_evaluated: int
    batches: int
    gradients: int
    wall_time_s: float
    history: list[dict] = field(default_factory=list)
    maximize: bool = False            # the objective was maximised (objective is the quantity itself)
    result_iteration: int = -1        # the iteration record the result is (best feasible point seen)
    last_iterate: bool = True         # False: the result is an earlier iterate than the optimiser's last
    feasibility_tolerance: float = FEASIBILITY_TOL
    error: str = ""                   # why the result point failed (a discipline's one line), else ''
    fd_failures: int = 0              # finite-difference points that failed (each gave a zero derivative)
    first_order: dict = field(default_factory=dict)  # first_order.check at the result point, with its cost
    verdict: str = ""                 # first_order's verdict: optimum | stopped before convergence | ...
    optimizer_success: bool = False   # what the optimiser itself said (scipy's success flag)
    multistart: dict = field(default_factory=dict)  # --starts N: multistart.run_starts's summary, else {}
    projected: dict = field(default_factory=dict)   # result just outside its bounds, projected onto them:
    # {"iteration": the record it was, "bound_violation_scaled": how far out (first_order.bound_violation)}, else {}
    stopped: str = ""                 # why the run stopped the optimiser (a discipline stopped answering), else ''

    def to_dict(self) -> dict:
        return asdict(self)

    def summary(self) -> dict:
        """``to_dict()`` without the history; ``ended``: the optimiser's last record where the result is another."""
        return {**{k: v for k, v in self.to_dict().items() if k != "history"},
                "ended": None if self.last_iterate or not self.history else self.history[-1]}


def _mda(run: RunSettings, evaluator: Evaluator, problem: Problem) -> MDA:
    return MDA(evaluator, **run.mda.as_dict(), guesses=problem.coupling_guesses, disciplines=list(run.disciplines))


def build_formulation(run: Run, evaluator: Evaluator, formulation: str | None = None) -> Formulation:
    """The MDF or IDF formulation of a run (RunSettings or a resolved config) over ``evaluator``."""
    run = RunSettings.of(run, evaluator)
    problem = run.optimisation_problem()
    name = (formulation or run.formulation).lower()
    if name not in FORMULATIONS:
        raise ValueError(f"formulation {name!r} is unknown; allowed: {', '.join(FORMULATIONS)}")
    opt = run.optimizer
    mda = _mda(run, evaluator, problem)
    return FORMULATIONS[name](problem, evaluator, mda, fd_step=opt.fd_step, fd_scheme=opt.fd_scheme,
                              derivatives=derivatives_mode(run, evaluator, list(mda.specs)))


def derivatives_mode(run: Run, evaluator: Evaluator, names: list[str]) -> str:
    """``optimizer.derivatives``: analytic | fd, or auto (the default): analytic when every
    discipline of the run provides partials, else fd (docs/derivatives.md: a mix of analytic and
    per-discipline finite differences is ``analytic``, chosen explicitly, because a batched
    finite-difference stencil of whole MDAs can cost less than an analysis plus a second wave)."""
    run = RunSettings.of(run, evaluator)
    mode = str(run.optimizer.derivatives).lower()
    if mode != "auto":
        return mode
    flags = [getattr(evaluator.specs.get(n), "partials", None) for n in names]
    # a transport that does not know (ROS): the run's settings say
    flags = [bool(run.partials.get(n, False)) if f is None else f for n, f in zip(names, flags)]
    return "analytic" if flags and all(flags) else "fd"


def _constraint_report(problem: Problem, values: Mapping[str, float], tol: float = FEASIBILITY_TOL) -> dict[str, dict]:
    out = {}
    for c in problem.constraints:
        y = float(values.get(c.name, np.nan))
        margins = [y - c.lower] if c.lower is not None else []
        margins += [c.upper - y] if c.upper is not None else []
        margin = float(min(margins))
        # each bound by its own scale, as the optimiser's rows (Problem.g): a two-sided limit was judged
        # on its upper side by the lower bound's scale
        violation = max((b - y if kind == "lower" else y - b) / s for kind, b, s in c.rows(monitored=True))
        out[c.name] = {"value": y, "lower": c.lower, "upper": c.upper, "margin": margin,
                       "satisfied": bool(np.isfinite(margin) and violation <= tol)}
    return out


def evaluate_design(run: Run, evaluator: Evaluator, design: Mapping[str, float]) -> dict:
    """One multidisciplinary analysis of ``design``; the JSON of ``bev-mdo evaluate``.

    ``design`` holds every design variable, and may add model-parameter overrides.
    """
    run = RunSettings.of(run, evaluator)
    problem = run.optimisation_problem()
    mda = _mda(run, evaluator, problem)
    problem.check_design(design, {p for s in mda.specs.values() for p in s.parameters})
    inputs = {k: np.array([float(v)]) for k, v in {**problem.parameters, **design}.items()}
    res = mda.run(inputs)
    values = {k: float(v[0]) for k, v in res.values.items()}
    why = res.errors[0]  # one design: the discipline's reason, without 'at point 0' and the inputs shown beside it
    error = (why.reason or why.message) if why is not None else ""
    short = design_check(run, problem, {**design, **values}) if res.ok[0] else []
    return design_report(problem, mda, design, values, bool(res.ok[0]), error, int(res.iterations[0]),
                         tol=run.optimizer.feasibility_tolerance, short=short)


def design_check(run: RunSettings, problem: Problem, values: Mapping[str, float]) -> list[str]:
    """``run.design_check``'s lines at one analysed point (``values``: its variables; the problem's parameters
    added): why the design is infeasible beyond its constraints (its motor cannot follow the cycle), [] if not."""
    return list(run.design_check({**problem.parameters, **values})) if run.design_check is not None else []


def design_report(problem: Problem, mda: MDA, design: Mapping[str, float], values: Mapping[str, float],
                  ok: bool, error: str, mda_iterations: int, tol: float = FEASIBILITY_TOL, short=()) -> dict:
    """The report of one analysed design (``values``: every MDA variable of the point; ``short``: its
    ``design_check`` lines, each making it infeasible)."""
    outputs = {v: float(values[v]) for s in mda.specs.values() for v in s.outputs}
    cons = _constraint_report(problem, outputs, tol)
    given = {k: float(v) for k, v in design.items()}
    params = {k: v for k, v in given.items() if k not in problem.names}  # --set overrides: not design variables
    return {
        "design": {k: v for k, v in given.items() if k in problem.names},
        **({"parameters": params} if params else {}),
        "outputs": outputs,
        "objective": {"name": problem.objective, "value": outputs.get(problem.objective, float("nan")),
                      **({"maximize": True} if problem.maximize else {})},
        "constraints": cons,
        "feasible": ok and all(c["satisfied"] for c in cons.values()) and not short,
        "ok": ok,
        "error": error,
        "mda_iterations": mda_iterations,
    }


def _physical_constraints(problem: Problem, g: np.ndarray) -> dict[str, float]:
    out = {}
    for (name, kind, bound, scale), gi in zip(problem.constraint_rows, g):
        out[name] = float(bound - gi * scale if kind == "lower" else bound + gi * scale)
    return out


def run_optimization(run: Run, evaluator: Evaluator, *, formulation: str | None = None,
                     optimizer: str | None = None, x0: Mapping[str, float] | None = None,
                     callback: Callable[[dict], Any] | None = None) -> RunResult:
    """Optimise the run's problem (RunSettings, or a resolved config) through ``evaluator``;
    ``callback(record)`` once per iteration."""
    t0 = time.perf_counter()
    run = RunSettings.of(run, evaluator)
    form = build_formulation(run, evaluator, formulation)
    problem = form.problem
    opt_cfg = run.optimizer
    opt_name = canonical_name(optimizer or opt_cfg.name)
    # the config's options belong to the config's optimiser: another one chosen here starts from none
    options = dict(opt_cfg.options) if not optimizer or canonical_name(opt_cfg.name) == opt_name else {}
    check_fit(opt_name, form)  # before the start point is evaluated and printed as iteration 0
    n_dv = len(problem.names)
    if x0:  # design variables; with IDF also its couplings (a resumed record's), else consistent ones
        unknown = [k for k in x0 if k not in form.var_names]
        if unknown:
            raise ValueError(f"x0 names {unknown} are not design variables {problem.names}"
                             + (f" or couplings {form.var_names[n_dv:]}" if len(form.var_names) > n_dv else ""))
        for j, n in enumerate(form.var_names):
            if n in x0:
                v = float(x0[n])
                if not form.lower[j] <= v <= form.upper[j]:
                    raise ValueError(f"x0 {n}={v:g} is outside the bounds [{form.lower[j]:g}, {form.upper[j]:g}]")
                form.x0[j] = v
        if hasattr(form, "start_at") and not any(n in x0 for n in form.var_names[n_dv:]):
            form.start_at(form.x0[:n_dv])
    tol = float(opt_cfg.feasibility_tolerance)
    sign = -1.0 if problem.maximize else 1.0  # evaluate_batch gives the minimised value
    form.feasibility_tolerance = tol
    history: list[dict] = []
    xs: list[np.ndarray] = []  # the optimiser variables of every record (IDF: with the couplings)
    kept: dict[bytes, tuple] = {}  # MDF: each record's full analysis (record)

    def follows(x: np.ndarray) -> bool:  # run.design_check at an evaluated point (under MDF its full analysis)
        if run.design_check is None:
            return True
        seen = form.analysed(x, again=True) if hasattr(form, "analysed") else None
        cons = _physical_constraints(problem, form.evaluate_batch(x[None, :])[1][0])
        return not design_check(run, problem, seen[0] if seen is not None and seen[1] else
                                {**dict(zip(form.var_names, map(float, x))), **cons})

    def record(x: np.ndarray) -> dict:
        x = np.asarray(x, dtype=float)
        f, g, h = form.evaluate_batch(x[None, :])
        ok, _ = form.status(x)
        viol = max(float(np.max(g[0], initial=0.0)), float(np.max(np.abs(h[0]), initial=0.0)),
                   form.bound_violation(x))  # a point outside the bounds is not feasible
        cons = _physical_constraints(problem, g[0])
        if not ok:  # the optimiser saw its penalty; the record says the point has no values (not 1e10, 720 K),
            # and no violation (NaN, as a sweep's failed design)
            cons = dict.fromkeys(cons, float("nan"))
        # the final verdict's judgement (design_check) at every record: multi-start picked a start whose motor
        # could not follow the cycle, its records and verdict 'feasible' where the final check said not
        short = ok and not follows(x)
        rec = {
            "iteration": len(history), "formulation": form.name, "optimizer": opt_name,
            "design": problem.design_dict(x[:n_dv]), "objective_name": problem.objective,
            "objective": sign * float(f[0]) if ok else float("nan"), "constraints": cons,
            "max_violation": viol if ok else float("nan"), "feasible": bool(ok and viol <= tol and not short),
            "mda_evaluations": form.mda_evaluations, "discipline_evaluations": dict(evaluator.counts),
            "wall_time_s": time.perf_counter() - t0, **({"cannot_follow": True} if short else {}),  # why infeasible
        }
        if len(form.var_names) > n_dv:  # IDF: the couplings the optimiser holds (a resume starts from them)
            rec["couplings"] = dict(zip(form.var_names[n_dv:], map(float, x[n_dv:])))
        history.append(rec)
        xs.append(x.copy())
        seen = form.analysed(x, again=True) if ok and hasattr(form, "analysed") else None
        if seen is not None and seen[1]:  # MDF: every record's full MDA, for the final report (a DE result
            kept[x.tobytes()] = seen      # can be 180 generations old, long out of the recent rows)
        if callback is not None:
            callback(rec)
        return rec

    if opt_name in GRADIENT_BASED:
        # its first step asks for the gradient at x0: x0 and its FD stencil go as ONE batch
        # (the same points; one MDA request instead of two)
        form.gradients(form.to_u(form.x0))
    record(form.x0.copy())
    start = form.x0.copy()
    for attempt in range(RESTARTS + 1):
        res = run_until_lost(opt_name, form, options, record, xs)
        x = np.asarray(res.x, dtype=float)
        if not history or history[-1]["design"] != problem.design_dict(x[:n_dv]):
            record(x)
        k = pick_result(history, sign, bool(res.success), tol)
        if res.get("stopped"):  # a record may repeat the optimiser's best so far (DE's, each generation): the
            k = next(i for i, xi in enumerate(xs) if np.array_equal(xi, xs[k]))  # result is where it was found
        checked_from = form.n_points, form.n_batches, time.perf_counter()
        fo = end_point_check(form, xs[k], start, tol, follows)
        if k != len(history) - 1 and history[-1]["feasible"] and not res.get("stopped"):
            # an optimiser that did not say it converged (SLSQP's last line search failed) at a point
            # the first-order check verifies has converged: as then, an earlier point more violated
            # than it does not displace it with the objective its violation buys
            fo_last = end_point_check(form, xs[-1], start, tol, follows)
            if fo_last["verdict"] == first_order.OPTIMUM:  # nor one the check does not verify (a small limit's
                j = pick_result(history, sign, True, tol)  # scale of 1 lets 1e-7 of it buy 1e-5 of objective)
                fo_j = fo_last if j == len(history) - 1 else fo if j == k else end_point_check(form, xs[j], start,
                                                                                                tol, follows)
                k, fo = (j, fo_j) if fo_j["verdict"] == first_order.OPTIMUM else (len(history) - 1, fo_last)
            fo["cost"] = {"points": form.n_points - checked_from[0], "batches": form.n_batches - checked_from[1],
                          "wall_time_s": time.perf_counter() - checked_from[2]}  # both checks
        last, x = history[k], xs[k]
        # A derivative-free method that says it converged where the first-order conditions do not hold
        # (its models went flat before a direction was resolved): once more from there, models rebuilt.
        if (attempt == RESTARTS or opt_name not in RESTARTABLE or not res.success
                or fo["verdict"] != first_order.STOPPED or set(options) & BUDGET_OPTIONS
                or fo["unknown_derivatives"]):  # failed points, not flat models: a restart cannot help
            break
        form.x0 = x.copy()
        first_message = str(res.message)
    # A result outside the bounds within the feasibility tolerance (COBYLA ended 5e-8 below Sellar's z2 >= 0, 6e-5
    # above SSBJ's x_shared[1] <= 60000: 'optimum', feasible) is projected onto them, evaluated, recorded and judged
    # there: a reported design is inside its bounds. A point further out is infeasible (its bound violation counts).
    projected = {}
    if last["feasible"] and not np.array_equal(np.clip(x, form.lower, form.upper), x):
        projected = {"iteration": k, "bound_violation_scaled": form.bound_violation(x)}
        record(np.clip(x, form.lower, form.upper))
        k = len(history) - 1
        last, x = history[k], xs[k]
        fo = end_point_check(form, x, start, tol, follows)
    if attempt:
        res.message = f"{res.message} (restarted once after: {first_message}; first-order check failed)"
    # The final report: MDF analysed the point already (its full MDA is kept); IDF's point is one more MDA through
    # the same evaluator, counted, so the totals equal what the disciplines evaluated (and what a recording holds).
    design = problem.design_dict(x[:n_dv])
    seen = kept.get(x.tobytes()) or (form.analysed(x) if hasattr(form, "analysed") else None)
    if seen is not None:  # a DE result recorded 180 iterations before the end, a discipline lost since
        short = design_check(run, problem, seen[0]) if seen[1] else []
        final = design_report(problem, form.mda, design, *seen, tol=tol, short=short)
        mda_evals = form.mda_evaluations
        ok, err = seen[1], seen[2]
    else:
        final = evaluate_design(run, evaluator, design)
        short = design_check(run, problem, {**design, **final["outputs"]}) if final.get("ok", True) else []
        mda_evals = form.mda_evaluations + 1
        ok, err = form.status(x)
        if ok and not final.get("ok", True):  # IDF: its point consistent, the MDA through it failed
            ok, err = False, final.get("error", "")
    counts = dict(evaluator.counts)
    if form.failures:  # points with no value, the optimiser's and the check's: how many, and the first one's cause
        fo = {**fo, "failed_points": form.failures, "first_failure": form.first_failure}
    if form.name == "mdf" and (outside := problem.outside_coupling_bounds(final["outputs"])):
        fo = {**fo, "outside_coupling_bounds": outside}  # IDF's bounds, not MDF's: said under the verdict
    if not ok and not fo.get("failure"):  # e.g. IDF's consistent point whose MDA failed, an MDA not converged
        fo = {**fo, "verdict": first_order.INFEASIBLE, "point_failed": True,
              "failure": (err or final.get("error", "")).split("; ")[0]}
    elif ok and short:  # infeasible whatever the constraints say: e.g. its energy is that of the cycle's demand
        fo = {**fo, "verdict": first_order.INFEASIBLE, "cannot_follow": short}
    message = str(res.message) + (f"; final point failed: {err}" if not ok else "")
    if projected:
        message += f"; the result is {projected_line(projected)}"
    elif k != len(history) - 1 and res.get("stopped"):
        message += (f"; the result is iteration {k}, the best feasible point seen" if last["feasible"] else
                    f"; no feasible point was seen: the result is iteration {k}")
    elif k != len(history) - 1:
        message += (f"; the result is iteration {k}, the best feasible point seen (the last iterate, iteration "
                    f"{len(history) - 1}, {'is worse' if history[-1]['feasible'] else 'is infeasible'}"
                    f"{': it cannot follow the drive cycle' if history[-1].get('cannot_follow') else ''})")
    return RunResult(
        formulation=form.name, optimizer=opt_name, success=fo["verdict"] == first_order.OPTIMUM and ok,
        message=message, design=design, objective_name=problem.objective,
        objective=float(last["objective"]), outputs=final["outputs"], constraints=final["constraints"],
        max_violation=float(last["max_violation"]), feasible=bool(last["feasible"] and final["feasible"]),
        iterations=len(history) - 1, mda_evaluations=mda_evals,
        discipline_evaluations=counts, points_evaluated=form.n_points, batches=form.n_batches,
        gradients=form.n_gradients, wall_time_s=time.perf_counter() - t0, history=history,
        maximize=problem.maximize, result_iteration=k, last_iterate=k == len(history) - 1,
        feasibility_tolerance=tol, error="" if ok else (err or final.get("error", "")).split("; ")[0],
        fd_failures=form.fd_failures, first_order=fo, verdict=fo["verdict"],
        optimizer_success=bool(res.success), projected=projected, stopped=res.get("stopped", ""))


def run_until_lost(name: str, form: Formulation, options, callback, xs: list[np.ndarray]) -> OptimizeResult:
    """``run_optimizer``, stopped as soon as a discipline is declared unresponsive (every attempt of a request timed
    out and nothing restarted it; in process, a call overran its budget: mdo/timed.py): every later point of it would
    fail at once, and a differential evolution ran 160 more generations of failed points to its maxiter. The stop is
    the formulation's (``stop_on_lost``: its next batch raises DisciplinesLost), so it reaches every optimiser. The
    result is then the last record (``xs[-1]``, physical), ``success`` False, and ``stopped``/``message`` say why."""
    form.stop_on_lost = True
    try:
        return run_optimizer(name, form, options, callback)
    except DisciplinesLost as exc:
        lost = ", ".join(repr(n) for n in exc.names)
        why = (f"stopped after iteration {len(xs) - 1}: discipline{'s' if len(exc.names) > 1 else ''} {lost} stopped "
               "answering (no answer within ros.timeout_s x (ros.retries + 1)); every later point would fail")
        return OptimizeResult(x=xs[-1].copy(), success=False, status=-1, nit=len(xs) - 1, message=why, stopped=why)
    finally:
        form.stop_on_lost = False


def projected_line(projected: dict) -> str:
    """What a result projected onto its bounds (``RunResult.projected``) was, for its message and the table."""
    return (f"iteration {projected['iteration']} projected onto the bounds (it was "
            f"{projected['bound_violation_scaled']:.2g} outside them, scaled: within the feasibility tolerance)")


OBJECTIVE_SCALE_HINT = 1e3  # an objective the optimiser sees this large, with no progress: problem.objective_scale


def end_point_check(form: Formulation, x: np.ndarray, x_start: np.ndarray, tol: float, follows=None) -> dict:
    """``first_order.check`` at the physical point ``x`` of ``form``, with what it cost: the gradient is
    the optimiser's last one when it was taken there (gradient-based runs), else one batched stencil
    (derivative-free runs). ``cost`` counts the points the check evaluated and its wall time. ``follows(x)``:
    the run's design_check at an evaluated point (for free_variables' steps)."""
    t0, points, batches = time.perf_counter(), form.n_points, form.n_batches
    x = np.asarray(x, dtype=float)
    u = form.u_of(x)
    f, g, h = form.evaluate_batch(x[None, :])
    ok, _ = form.status(x)  # after the evaluation: a point not evaluated before read as failed
    if ok:
        df, dg, dh = form.gradients(u)
        df = df / form.problem.objective_scale
        ok, _ = form.status(x)  # analytic partials evaluate x again: a discipline may fail there now
    if not ok:  # a failed point has no derivative: its verdict is infeasible
        df, dg, dh = np.zeros(form.n), np.zeros((g.shape[1], form.n)), np.zeros((h.shape[1], form.n))
    lo, hi = form.u_bounds

    def judge(df, dg, dh) -> dict:
        return first_order.check(u, lo, hi, df, g[0], dg, h[0], dh, names=form.var_names,
                                 ineq_labels=form.ineq_labels, eq_labels=form.eq_labels, feasibility_tol=tol,
                                 point_ok=ok, moved=not np.allclose(x, np.asarray(x_start, dtype=float), rtol=1e-12,
                                                                    atol=1e-12),  # a rounding away is no move
                                 unknown=form.unknown_derivatives(u) if ok else ())

    fo = {**judge(df, dg, dh), "derivatives": form.derivatives}  # what the numbers are computed on: analytic | fd
    if ok and fo["verdict"] in (first_order.STOPPED, first_order.NO_PROGRESS) and form.derivatives == "fd" \
            and form.fd_scheme == "forward" and not fo["unknown_derivatives"]:
        # forward errs by h f''/2 (a narrow well's true minimum read 0.004, "stopped"): an optimum on central ones is
        # taken, its kinks looked for as at a point that is not one (they average a concave kink's slopes to 0)
        (cf, cg, ch), unknown = form.fd_gradients(u, form.fd_step)
        if not unknown and (again := judge(cf / form.problem.objective_scale, cg, ch))["verdict"] == first_order.OPTIMUM:
            fo, df, dg, dh = ({**again, "derivatives": "fd", "fd_scheme_checked": "central"},
                              cf / form.problem.objective_scale, cg, ch)
    first_order.limit_rates(fo, form.problem, form.var_names, form.scale, (form.lower, form.upper))  # physical
    if ok and fo["verdict"] == first_order.OPTIMUM and form.derivatives == "analytic":
        # the gradient came from the disciplines' partials, which its own check cannot doubt: a wrong partial
        # (df/dz 3z for 2z) ended "optimum" 3.4e-4 above the optimum. Central differences at steps h and 2h
        # (two batches) must agree with it, where the conditions are judged, beyond their own difference.
        wrong = derivatives_disagree(form, u, g[0], (df, dg, dh))
        fo["derivatives_confirmed"] = not wrong
        if wrong:
            fo.update(verdict=first_order.STOPPED, conditions_hold=False, derivatives_disagree=wrong)
    if ok and fo["verdict"] != first_order.INFEASIBLE and not fo["unknown_derivatives"]:  # is it smooth there?
        # an optimum too: a gradient taken across a kink mixes its one-sided slopes, and the mix can meet the
        # conditions by chance (x + y with max(x, y) == 1 at (1, 1): "optimum", while (1, 0) is lower). No test on
        # one-sided slopes settles it (two reviewers: both sides' slopes met them at a corner that descends along
        # (t, -t), and failed true optima with curvature): the optimum is not verified, the kink named
        optimum, before = fo["verdict"] == first_order.OPTIMUM, form.n_points
        fo["kinks"] = end_point_kinks(form, u, f[0], g[0], h[0], float(np.max(np.abs(df), initial=0.0)),
                                      at_optimum=optimum and "fd_scheme_checked" not in fo,
                                      failed=fo.setdefault("failed_steps", []))
        fo["kink_points"] = form.n_points - before  # of the check's cost: the steps either side
        if optimum and fo["kinks"]:
            fo.update(verdict=first_order.STOPPED, conditions_hold=False, kink_at_optimum=True)
    if ok and fo["verdict"] == first_order.OPTIMUM:  # a variable nothing holds: the optimum is not unique in it
        before = form.n_points
        if free := free_variables(form, u, float(f[0]), g[0], (df, dg, dh), fo, tol, follows):
            fo["free_variables"] = free
        if form.n_points > before:
            fo["free_points"] = form.n_points - before  # of the check's cost: the steps along them
    seen = abs(float(f[0])) / form.problem.objective_scale  # the objective as the optimiser sees it
    if ok and fo["verdict"] == first_order.NO_PROGRESS and seen >= OBJECTIVE_SCALE_HINT:
        fo["objective_seen"] = seen  # an objective of 1e6 stopped SLSQP at its first point, with no hint
    fo["cost"] = {"points": form.n_points - points, "batches": form.n_batches - batches,
                  "wall_time_s": time.perf_counter() - t0}
    return fo


def derivatives_disagree(form: Formulation, u: np.ndarray, g: np.ndarray, analytic) -> dict | None:
    """The total of the first-order conditions (the objective, the active inequalities, the equalities) whose
    analytic value (``analytic``: the check's df, dg, dh) differs most from central differences at ``u``, if one
    differs by more than 10 x the differences' own change from step h to 2h plus 1e-3 of its size (and
    first_order.FIRST_ORDER_TOL of the gradient's); None when all agree or the differences failed somewhere."""
    (f1, u1), (f2, u2) = form.fd_gradients(u, form.fd_step), form.fd_gradients(u, 2.0 * form.fd_step)
    if u1 or u2:
        return None
    rows = np.concatenate([[0], 1 + np.flatnonzero(np.asarray(g) >= -first_order.ACTIVE_TOL),
                           1 + len(g) + np.arange(len(form.eq_labels))])
    scale = np.concatenate([[form.problem.objective_scale], np.ones(len(g) + len(form.eq_labels))])[rows, None]
    a, b, c = (np.vstack([d[0][None, :], d[1], d[2]])[rows] for d in (analytic, f1, f2))
    b, c = b / scale, c / scale  # the check's df is per objective_scale, as analytic's
    ref = first_order.FIRST_ORDER_TOL * max(1.0, float(np.max(np.abs(a[0]), initial=0.0)))
    gap = np.abs(a - b) - 10.0 * np.abs(b - c) - 1e-3 * np.maximum(np.abs(a), np.abs(b)) - ref
    if not (gap > 0).any():
        return None
    i, j = np.unravel_index(int(np.argmax(gap)), gap.shape)
    names = [form.problem.objective, *form.ineq_labels, *form.eq_labels]
    return {"of": names[rows[i]], "wrt": form.var_names[j], "analytic": float(a[i, j]), "fd": float(b[i, j])}
