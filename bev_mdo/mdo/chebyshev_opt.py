"""Optimiser ``chebyshev-pairwise``: the thesis' sensitivity-guided Chebfun2 procedure (Fig 7-19).

Each iteration:
1. sensitivities of the objective at x (one FD stencil batch, :mod:`.sensitivity`) rank
   the variables; the most sensitive free one is paired with its strongest second-order
   partner (then the other pairs, in order, if that pair makes no progress);
2. 2-D Chebyshev proxies of f and every g over a trust box around x in that pair (one
   batch per degree) give the constrained global minimum of the proxy (Fig 7-20/7-21);
3. the true point is evaluated; if a constraint is violated, root finding on the
   constraint proxies along the step restores feasibility (Fig 7-22).
No pair improves -> the box halves; the run stops when the box is below ``xtol``.
An infeasible start is first moved onto the zero contour of the most violated constraint.

Ranking uses range-scaled derivatives |df/dx_i| (u_i - l_i) (the normalised S_i of
eq 5-4 is undefined where f = 0); the partner maximises |d2f/dx_i dx_j| r_i r_j.
"""
from __future__ import annotations

from typing import Any, Callable, Mapping

import numpy as np
from scipy.optimize import OptimizeResult

from bev_mdo.models.common import is_number, text_hint

from .chebyshev import chebfun1, chebfun2, on_plane
from .sensitivity import sensitivities

DEFAULTS = {"box": 0.25, "xtol": 1e-7, "ftol": 1e-12, "ctol": 1e-8, "maxiter": 200,
            "cheb_tol": 1e-11, "cheb_n_max": 32, "rel_step": 1e-4}
# tolerances and sizes that must be finite and > 0 (>= 0: ftol, ctol); a NaN box never fell below xtol
_POSITIVE = ("box", "xtol", "cheb_tol", "rel_step")


def check_options(options: Mapping[str, Any] | None) -> dict:
    """DEFAULTS with ``options`` over them; ValueError (one line naming ``optimizer.options.<key>``) for a
    key not in DEFAULTS or a tolerance out of its range (the counts are checked with every optimiser's:
    config/sections.py). The config check runs it at load."""
    o = dict(DEFAULTS)
    for k, v in (options or {}).items():
        if k not in DEFAULTS:
            raise ValueError(f"unknown chebyshev-pairwise option {k!r} (known: {', '.join(DEFAULTS)})")
        o[k] = v
    for k in ("ftol", "ctol", *_POSITIVE):
        v = o[k]
        if not is_number(v) or not np.isfinite(v) or v < 0 or (v == 0 and k in _POSITIVE):
            raise ValueError(f"optimizer.options.{k}: {v!r} must be a finite number "
                             f"{'> 0' if k in _POSITIVE else '>= 0'} (chebyshev-pairwise){text_hint(v)}")
    return o


class _Counted:
    """Wraps batch_fun: counts points and batches; returns (f, g (N, m))."""

    def __init__(self, batch_fun):
        self.fun, self.nfev, self.nbatch = batch_fun, 0, 0

    def __call__(self, X):
        X = np.atleast_2d(np.asarray(X, dtype=float))
        f, g = self.fun(X)
        self.nfev += X.shape[0]
        self.nbatch += 1
        f = np.asarray(f, dtype=float).reshape(X.shape[0])
        g = np.asarray(g, dtype=float).reshape(X.shape[0], -1)
        return f, g

    def as_dict(self, X):
        f, g = self(X)
        return {"f": f, **{f"g{k}": g[:, k] for k in range(g.shape[1])}}


def _check(x0, lower, upper):
    x0, lo, hi = (np.asarray(a, dtype=float).ravel() for a in (x0, lower, upper))
    if not (x0.shape == lo.shape == hi.shape):
        raise ValueError(f"x0, lower, upper must have one shape, got {x0.shape}, {lo.shape}, {hi.shape}")
    if x0.size < 2:
        raise ValueError("chebyshev-pairwise needs at least 2 design variables")
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(lo < hi)):
        raise ValueError("chebyshev-pairwise needs finite bounds with lower < upper on every variable")
    return np.clip(x0, lo, hi), lo, hi


def _pairs(ev, x, lo, hi, rel_step, key="f"):
    """Variable pairs ordered by the sensitivity ranking of output ``key`` (first, then second order)."""
    n = len(x)
    names = [f"x{i}" for i in range(n)]
    s = sensitivities(ev.as_dict, dict(zip(names, x)), order=2, rel_step=rel_step,
                      bounds={k: (a, b) for k, a, b in zip(names, lo, hi)})
    r = hi - lo
    grad, hess = s.gradient[key], s.hessian[key]
    score = np.abs(grad) * r
    # A variable on a bound whose descent direction leaves the box cannot move.
    free = ~(((x <= lo) & (grad > 0)) | ((x >= hi) & (grad < 0)))
    order = sorted(range(n), key=lambda i: (not free[i], -score[i]))
    coupling = np.abs(hess) * np.outer(r, r)
    pairs = []
    for i in order:
        for j in sorted((j for j in range(n) if j != i), key=lambda j: (-coupling[i, j], -score[j])):
            p = tuple(sorted((i, j)))
            if p not in pairs:
                pairs.append(p)
    return pairs


def _box(x, lo, hi, i, j, delta):
    r = hi - lo
    return [(max(lo[k], x[k] - delta * r[k]), min(hi[k], x[k] + delta * r[k])) for k in (i, j)]


def _pair_step(ev, x, lo, hi, i, j, delta, o):
    """Constrained proxy minimum in the (i, j) trust box, or None."""
    (ax, bx), (ay, by) = _box(x, lo, hi, i, j, delta)
    if bx - ax <= 0 or by - ay <= 0:
        return None
    prox = chebfun2(on_plane(ev.as_dict, x, i, j), (ax, bx), (ay, by), tol=o["cheb_tol"], n_max=o["cheb_n_max"])
    cons = [p for k, p in prox.items() if k != "f"]
    best = prox["f"].minimum(cons)
    if best is None:
        return None
    y = x.copy()
    y[i], y[j] = best[0], best[1]
    return y


def _restore_on_segment(ev, x, y, o):
    """Largest t in [0, 1] with every constraint feasible on x + t (y - x) (1-D proxy roots)."""
    def seg(T):
        return ev.as_dict(x + T[:, :1] * (y - x))
    prox = chebfun1(seg, 0.0, 1.0, tol=o["cheb_tol"], n_max=64)
    cuts = [1.0]
    for k, p in prox.items():
        if k != "f":
            cuts += [t for t in p.roots() if t > 0]
    for t in sorted(set(cuts), reverse=True):
        if all(float(p(t)) <= o["ctol"] for k, p in prox.items() if k != "f"):
            return x + t * (y - x)
    return None


NO_START = "chebyshev-pairwise: could not find a feasible start point"


class InfeasibleStart(ValueError):
    """No feasible start point was found; ``g``: the constraints (g <= 0 feasible) where the search ended,
    ``constraint``: the index of one that could not be satisfied (the caller names them: run_optimizer)."""

    def __init__(self, message: str, g, constraint: int):
        super().__init__(message)
        self.g, self.constraint = np.asarray(g, dtype=float).ravel(), constraint


def _restore(ev, x, lo, hi, o, max_rounds=10):
    """Fig 7-22: move an infeasible x onto the feasible side of its most violated constraint."""
    f, g = ev(x[None])
    for _ in range(max_rounds):
        if g.size == 0 or g.max() <= o["ctol"]:
            return x, f[0], g[0]
        k = int(np.argmax(g[0]))
        i, j = _pairs(ev, x, lo, hi, o["rel_step"], key=f"g{k}")[0]
        y = _pair_step(ev, x, lo, hi, i, j, 1.0, o)
        if y is None:  # no feasible point in the pair's range: nearest point on g_k = 0
            prox = chebfun2(on_plane(lambda X: ev.as_dict(X)[f"g{k}"], x, i, j),
                            (lo[i], hi[i]), (lo[j], hi[j]), tol=o["cheb_tol"], n_max=o["cheb_n_max"])
            z = prox.zero_contour(41)
            if len(z) == 0:
                raise InfeasibleStart(NO_START, np.where(g[0] > o["ctol"], g[0], 0.0), k)
            r = np.array([hi[i] - lo[i], hi[j] - lo[j]])
            zi = z[np.argmin(np.sum(((z - x[[i, j]]) / r) ** 2, axis=1))]
            y = x.copy()
            y[i], y[j] = zi
        x = y
        f, g = ev(x[None])
    raise InfeasibleStart(NO_START, np.where(g[0] > o["ctol"], g[0], 0.0), int(np.argmax(g[0])))


def minimize(batch_fun: Callable, x0, lower, upper, options: Mapping[str, Any] | None = None,
             callback: Callable[[np.ndarray], Any] | None = None) -> OptimizeResult:
    """Sensitivity-guided pairwise Chebyshev minimisation of f s.t. g <= 0 (module docstring)."""
    o = check_options(options)
    x, lo, hi = _check(x0, lower, upper)
    ev = _Counted(batch_fun)
    x, f, g = _restore(ev, x, lo, hi, o)
    delta, nit, pairs_tried, message = float(o["box"]), 0, 0, "maximum number of iterations reached"
    while nit < o["maxiter"]:
        if delta < o["xtol"]:
            message = "trust box below xtol"
            break
        improved = False
        for i, j in _pairs(ev, x, lo, hi, o["rel_step"]):
            pairs_tried += 1
            y = _pair_step(ev, x, lo, hi, i, j, delta, o)
            if y is None:
                continue
            fy, gy = ev(y[None])
            if gy.size and gy.max() > o["ctol"]:
                y = _restore_on_segment(ev, x, y, o)
                if y is None:
                    continue
                fy, gy = ev(y[None])
                if gy.size and gy.max() > o["ctol"]:
                    continue
            if fy[0] < f - o["ftol"] * max(abs(f), 1.0):
                step = np.max(np.abs(y - x) / (hi - lo))
                x, f, g = y, fy[0], gy[0]
                improved = True
                nit += 1
                if callback is not None:
                    callback(x.copy())
                if step >= 0.9 * delta:
                    delta = min(2 * delta, 0.5)
                break
        if not improved:
            delta *= 0.5
    converged = message == "trust box below xtol"  # the iteration limit is no convergence (as scipy's status 9)
    feasible = g.size == 0 or g.max() <= o["ctol"]
    return OptimizeResult(x=x, fun=float(f), constr=g, success=bool(converged and feasible),
                          status=0 if converged else 9, message=message, nit=nit, nfev=ev.nfev, nbatch=ev.nbatch,
                          pairs_tried=pairs_tried, trust_box=delta)
