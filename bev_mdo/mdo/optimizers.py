"""Optimiser registry: scipy.optimize methods on a formulation, plus lazy plug-ins.

An entry of ``OPTIMIZERS`` is either a callable ``fn(formulation, options, callback)``
that works in scaled variables, or a ``"module:function"`` string naming a batch
optimiser with the signature
``minimize(batch_fun, x0, lower, upper, options, callback) -> OptimizeResult``
where ``batch_fun(X (N, n) physical) -> (f (N,), g (N, m))`` and g <= 0 is feasible.
``run_optimizer`` returns an OptimizeResult whose ``x`` is in physical units and calls
``callback(x_physical)`` once per iteration.
"""
from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from scipy.optimize import (BFGS, Bounds, NonlinearConstraint, OptimizeResult,
                            differential_evolution, minimize)

from bev_mdo.mdo.settings import FEASIBILITY_TOL

Callback = Callable[[np.ndarray], Any]
NOISE_VIOLATION = 1e-3  # x the feasibility tolerance: a violation this small is numerical noise


def _cb(form, callback: Callback | None):
    if callback is None:
        return None

    def cb(xk, *args, **kwargs):  # legacy scipy signature: (xk[, state|convergence])
        callback(form.to_x(np.asarray(xk, dtype=float)))
    return cb


LINESEARCH_FAILED = 8  # SLSQP: "Positive directional derivative for linesearch"
SLSQP_RESTARTS = 2


def _slsqp(form, options: Mapping[str, Any], callback):
    """SLSQP; when its line search fails (a stale quasi-Newton Hessian, or a gradient at the level of
    finite-difference noise), it restarts from the point it reached with a fresh Hessian, at most
    SLSQP_RESTARTS times, and the message says so (the first-order check judges the end point)."""
    form.speculative_gradients = True
    opts = {"maxiter": 200, "ftol": 1e-10, **options}
    cons = [{"type": "ineq", "fun": form.ineq, "jac": form.ineq_jac}] if form.ineq_labels else []
    if form.eq_labels:
        cons.append({"type": "eq", "fun": form.eq, "jac": form.eq_jac})
    u, notes, nit = form.to_u(form.x0), [], 0
    for attempt in range(SLSQP_RESTARTS + 1):
        res = minimize(form.fun, u, jac=form.jac, bounds=Bounds(*form.u_bounds), method="SLSQP",
                       constraints=cons, options=opts, callback=_cb(form, callback))
        nit += int(res.get("nit", 0))
        if res.status != LINESEARCH_FAILED or attempt == SLSQP_RESTARTS or np.array_equal(res.x, u):
            break
        notes.append(f"restart {attempt + 1} after: {res.message}")
        u = np.asarray(res.x, dtype=float)
        opts["maxiter"] = max(1, int(opts["maxiter"]) - int(res.get("nit", 0)))
    res.nit = nit
    if notes:
        res.message = f"{res.message} ({'; '.join(notes)})"
    return res


def _trust_constr(form, options, callback):
    form.speculative_gradients = True
    opts = {"maxiter": 500, "gtol": 1e-10, "xtol": 1e-10, "initial_barrier_parameter": 1e-8,
            "initial_barrier_tolerance": 1e-8, **options}  # small barrier: optima sit on bounds
    cons = []
    if form.ineq_labels:
        cons.append(NonlinearConstraint(lambda u: -form.ineq(u), -np.inf, 0.0,
                                        jac=lambda u: -form.ineq_jac(u), hess=BFGS()))
    if form.eq_labels:
        cons.append(NonlinearConstraint(form.eq, 0.0, 0.0, jac=form.eq_jac, hess=BFGS()))
    # bounds not keep_feasible: it ends infeasible on Golinski, SSBJ MDF and propane IDF; a point outside
    # the bounds is evaluated but counts as violated (first_order.bound_violation), never the result
    return minimize(form.fun, form.to_u(form.x0), jac=form.jac, hess=BFGS(), bounds=Bounds(*form.u_bounds),
                    method="trust-constr", constraints=cons, options=opts, callback=_cb(form, callback))


def start_radius(form) -> float:
    """A derivative-free method's first step: a tenth of the smallest finite range of the scaled
    variables (design variables span 1 by default; IDF couplings without bounds do not count)."""
    lo, hi = form.u_bounds
    spans = (hi - lo)[np.isfinite(hi - lo)]
    return 0.1 * float(np.min(spans)) if spans.size else 0.1


def _derivative_free(method: str):
    def run(form, options, callback):
        opts = {"maxiter": 2000, **options}
        radius = start_radius(form)
        if method == "COBYLA":
            opts = {"tol": 1e-10, "rhobeg": radius, **opts}
        else:
            opts = {"initial_tr_radius": radius, "final_tr_radius": 1e-8, **opts}
        cons = []
        if form.ineq_labels:
            cons.append({"type": "ineq", "fun": form.ineq})
        if form.eq_labels:  # COBYLA: as two inequalities
            if method == "COBYLA":
                cons += [{"type": "ineq", "fun": form.eq}, {"type": "ineq", "fun": lambda u: -form.eq(u)}]
            else:
                cons.append({"type": "eq", "fun": form.eq})
        u0 = form.to_u(form.x0)
        res = minimize(form.fun, u0, bounds=Bounds(*form.u_bounds), method=method, constraints=cons, options=opts,
                       callback=_cb(form, callback))
        if method == "COBYQA" and np.array_equal(res.x, u0) and "maxfev" not in options and "maxiter" not in options:
            # COBYQA returns its best point among those within its feasibility_tol (absolute, 1.5e-8); on
            # IDF's consistency equalities its models may end just above that (2e-8..3e-8, by BLAS kernel),
            # and it returned the start point. It restarts once from the best point it evaluated within the
            # violation the driver treats as noise; the first-order check judges where it ends.
            best = form.best_seen(NOISE_VIOLATION * getattr(form, "feasibility_tolerance", FEASIBILITY_TOL))
            if best is not None and not np.array_equal(best, u0):
                again = minimize(form.fun, best, bounds=Bounds(*form.u_bounds), method=method, constraints=cons,
                                 options=opts, callback=_cb(form, callback))
                again.message = f"{again.message} (restarted from the best point seen after: {res.message})"
                again.nfev = int(again.get("nfev", 0)) + int(res.get("nfev", 0))
                res = again
        return res
    return run


# optimisers that sample the whole box: every optimiser variable needs finite bounds
FINITE_BOUNDS = frozenset({"differential_evolution", "chebyshev-pairwise"})


def check_fit(name: str, form) -> None:
    """What optimiser ``name`` needs of ``form``: finite bounds (``check_finite_bounds``); and a note (CycleNote)
    where IDF's consistency equalities meet an optimiser of SEARCH_ON_VALUES."""
    check_finite_bounds(name, form)
    if form.eq_labels and name in SEARCH_ON_VALUES:
        import warnings

        from bev_mdo.models.cycles import CycleNote

        warnings.warn(f"{name} under IDF: its {len(form.eq_labels)} consistency equalities hold only where a point it "
                      "tries happens to meet them, so it may end where it started (--formulation mdf meets them by the "
                      "MDA)", CycleNote, stacklevel=3)


def check_finite_bounds(name: str, form) -> None:
    """ValueError, before anything is evaluated, when optimiser ``name`` samples the box and a variable of
    ``form`` has no finite bound (IDF's coupling variables without ``problem.coupling_bounds``)."""
    lo, hi = form.u_bounds
    if name in FINITE_BOUNDS and not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        raise ValueError(f"{name} needs finite bounds on every optimiser variable "
                         "(with IDF give problem.coupling_bounds)")


FAIL_VIOLATION = 1e100  # differential evolution: a failed point is worse than any real design


def _differential_evolution(form, options, callback):
    check_finite_bounds("differential_evolution", form)
    lo, hi = form.u_bounds

    def cols(U):
        U = np.asarray(U, dtype=float)
        return U[:, None] if U.ndim == 1 else U  # (n, S)

    def f(U):
        F, _, _ = form.evaluate_batch(form.to_x(cols(U).T))
        return F / form.problem.objective_scale

    def rows(U, which):
        # scipy ranks infeasible members by their summed violation: a failed point's FAIL_CONSTRAINT
        # (1 per row) would rank it above a real design missing every bound by more than 1
        X = form.to_x(cols(U).T)
        out = form.evaluate_batch(X)[which]
        out[form.failed_rows(X)] = FAIL_VIOLATION
        return out.T

    def g(U):
        return rows(U, 1)

    def h(U):
        return rows(U, 2)

    cons = []
    if form.ineq_labels:
        cons.append(NonlinearConstraint(g, -np.inf, 0.0))
    if form.eq_labels:
        cons.append(NonlinearConstraint(h, -form.eq_tolerance, form.eq_tolerance))
    # a user's own 'seed' (scipy's older name of rng) replaces the default rng: both at once are a TypeError
    opts = {"maxiter": 200, "popsize": 15, "tol": 1e-8, "polish": False, **({} if "seed" in options else {"rng": 0}),
            **options}
    opts.update(vectorized=True, updating="deferred")
    return differential_evolution(f, Bounds(lo, hi), constraints=cons, x0=form.to_u(form.x0),
                                  callback=_cb(form, callback), **opts)


OPTIMIZERS: dict[str, Callable | str] = {
    "SLSQP": _slsqp,
    "trust-constr": _trust_constr,
    "COBYQA": _derivative_free("COBYQA"),
    "COBYLA": _derivative_free("COBYLA"),
    "differential_evolution": _differential_evolution,
    "chebyshev-pairwise": "bev_mdo.mdo.chebyshev_opt:minimize",
}

# options of the shipped optimisers that count something (iterations, evaluations, population members
# per variable, Chebyshev terms): a whole number of at least 1 (maxiter: -5 ran no iteration at all)
COUNT_OPTIONS = frozenset({"maxiter", "maxfev", "popsize", "cheb_n_max"})


# Optimisers that draw random numbers: a run's seed (optimize --seed, Study.optimize's seed) seeds one whose
# options give no seed (or rng) of their own; 0, the run's default, is their default rng here too.
SEEDED = frozenset({"differential_evolution"})

# Optimisers with no model of the constraints (a population, a proxy of the objective): IDF's consistency equalities
# hold only where a point happens to meet them (chebyshev-pairwise ran 200 iterations, 206 s, and did not move)
SEARCH_ON_VALUES = frozenset({"differential_evolution", "chebyshev-pairwise"})
# Optimisers whose first step needs the gradient at x0 (the driver evaluates x0 with its FD stencil).
GRADIENT_BASED = frozenset({"SLSQP", "trust-constr"})
# Optimisers of which one process runs one at a time: scipy holds a module lock (COBYQA_LOCK) through each
# COBYQA minimisation, so starts in lockstep (multistart.py) waited for each other's wave and the lock forever.
ONE_AT_A_TIME = frozenset({"COBYQA"})


def canonical_name(name: str) -> str:
    """Registry key for ``name`` (case-insensitive); ValueError lists the allowed names."""
    for key in OPTIMIZERS:
        if key.lower() == str(name).lower():
            return key
    raise ValueError(f"optimizer {name!r} is unknown; allowed: {', '.join(OPTIMIZERS)}")


def _load(spec: str) -> Callable:
    mod, _, fn = spec.partition(":")
    try:
        return getattr(importlib.import_module(mod), fn)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"optimizer plug-in {spec!r} is not available: {exc}") from None


def infeasible_start(message: str, form, g: np.ndarray, worst: int) -> str:
    """One line for a plug-in that found no feasible start: the constraints of ``batch_fun`` (``g``,
    normalised, > 0 violated) it could not satisfy, by how much in their units, and what to do."""
    rows = form.problem.constraint_rows
    labels = form.ineq_labels + [f"{e} (|residual| <= {form.eq_tolerance:g})" for e in form.eq_labels]
    order = [worst] + [i for i in np.argsort(-g) if g[i] > 0 and i != worst][:2]
    parts = []
    for i in order:
        by = f"{g[i] * rows[i][3]:.4g}" if i < len(rows) else f"{g[i]:.3g} (normalised)"
        parts.append(f"{labels[i]} violated by {by}")
    return (f"{message}: {'; '.join(parts)}; start from a design that satisfies "
            f"{'it' if len(parts) == 1 else 'them'} (--initial NAME=X) or use another optimizer (SLSQP, COBYLA)")


def run_optimizer(name: str, form, options: Mapping[str, Any] | None = None,
                  callback: Callback | None = None) -> OptimizeResult:
    """Run optimiser ``name`` on ``form``; the result's ``x`` is physical."""
    entry = OPTIMIZERS[canonical_name(name)]
    options = dict(options or {})
    if isinstance(entry, str):
        try:
            res = _load(entry)(form.batch_fun, form.x0.copy(), form.lower.copy(), form.upper.copy(),
                               options, callback)
        except ValueError as exc:
            if getattr(exc, "g", None) is None:
                raise
            raise ValueError(infeasible_start(str(exc), form, exc.g, exc.constraint)) from None
        res.x = np.asarray(res.x, dtype=float)
        return res
    res = entry(form, options, callback)
    res.x = form.to_x(res.x)
    return res
