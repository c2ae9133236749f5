"""Chebyshev proxies (the thesis' Chebfun/Chebfun2 role) of batched functions.

Interpolants on Chebyshev points of the second kind x_j = cos(j*pi/n) (eq 7-2),
coefficients by DCT-I; the degree doubles until the trailing coefficients fall below
``tol`` times the largest one. Doubling reuses the previous (nested) points, and each
grid is ONE call of the batch function. ``fun`` takes X (N, 1) or (N, 2) and returns
an (N,) array or a dict of them (then one proxy per output from the same grid).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np
from numpy.polynomial import chebyshev as C
from scipy.fft import dct
from scipy.optimize import brentq, minimize

DEFAULT_TOL = 1e-12
N_START = 8


def chebpts2(n: int) -> np.ndarray:
    """n+1 Chebyshev points of the second kind on [-1, 1], descending (eq 7-2)."""
    return np.cos(np.pi * np.arange(n + 1) / n)


def vals2coeffs(values: np.ndarray, axes=(0,)) -> np.ndarray:
    """Chebyshev coefficients of values at ``chebpts2`` along ``axes`` (DCT-I)."""
    c = np.asarray(values, dtype=float)
    for ax in axes:
        n = c.shape[ax] - 1
        c = dct(c, type=1, axis=ax) / n
        sl = [slice(None)] * c.ndim
        for end in (0, -1):
            sl[ax] = end
            c[tuple(sl)] /= 2.0
    return c


def _check_range(a, b, name):
    a, b = float(a), float(b)
    if not (np.isfinite(a) and np.isfinite(b) and a < b):
        raise ValueError(f"range of {name} must be finite with lower < upper, got [{a}, {b}]")
    return a, b


def _to_unit(x, a, b):
    return (2.0 * np.asarray(x, dtype=float) - (a + b)) / (b - a)


def _from_unit(t, a, b):
    return 0.5 * (a + b) + 0.5 * (b - a) * np.asarray(t, dtype=float)


def _tail_small(c: np.ndarray, axis: int, tol: float) -> bool:
    tail = np.take(c, [-3, -2, -1], axis=axis)
    return bool(np.max(np.abs(tail)) <= tol * np.max(np.abs(c)))


def _chop(c: np.ndarray, tol: float) -> np.ndarray:
    """Drop trailing rows/columns whose coefficients are all below tol*max."""
    thr = tol * max(np.max(np.abs(c)), 1e-300)
    for ax in range(c.ndim):
        keep = c.shape[ax]
        while keep > 1 and np.max(np.abs(np.take(c, [keep - 1], axis=ax))) <= thr:
            keep -= 1
        c = np.take(c, np.arange(keep), axis=ax)
    return c


def _as_dict(out, n):
    single = not isinstance(out, Mapping)
    d = {"f": out} if single else dict(out)
    res = {}
    for k, v in d.items():
        v = np.asarray(v, dtype=float)
        if v.shape != (n,):
            raise ValueError(f"output {k!r} has shape {v.shape}, expected ({n},)")
        if not np.all(np.isfinite(v)):
            raise ValueError(f"output {k!r} is not finite on the Chebyshev grid")
        res[k] = v
    return res, single


@dataclass
class Cheb1:
    """1-D Chebyshev proxy on [a, b]."""

    coef: np.ndarray
    domain: tuple[float, float]
    converged: bool = True
    n_evaluations: int = 0

    def __call__(self, x):
        return C.chebval(_to_unit(x, *self.domain), self.coef)

    def deriv(self) -> "Cheb1":
        a, b = self.domain
        c = C.chebder(self.coef) * (2.0 / (b - a)) if len(self.coef) > 1 else np.zeros(1)
        return Cheb1(c, self.domain, self.converged)

    def roots(self) -> np.ndarray:
        """Real roots in the domain (chebroots, then brentq on the proxy)."""
        return _roots_1d(self.coef, lambda t: C.chebval(t, self.coef), *self.domain)

    def minimum(self) -> tuple[float, float]:
        """Global minimum (x, f) over the domain: critical points + end points."""
        a, b = self.domain
        xs = np.concatenate([[a, b], self.deriv().roots()])
        fs = self(xs)
        i = int(np.argmin(fs))
        return float(xs[i]), float(fs[i])


def _roots_1d(coef, f_unit, a, b, pad=1e-7):
    coef = np.trim_zeros(np.asarray(coef, dtype=float), "b")
    if len(coef) < 2:
        return np.empty(0)
    r = C.chebroots(coef)
    r = np.real(r[(np.abs(r.imag) < 1e-6) & (np.abs(r.real) <= 1 + 1e-6)])
    out = []
    for t in np.sort(np.clip(r, -1, 1)):
        lo, hi = max(t - pad, -1.0), min(t + pad, 1.0)
        flo, fhi = f_unit(lo), f_unit(hi)
        if flo == 0:
            t = lo
        elif fhi == 0:
            t = hi
        elif flo * fhi < 0:
            t = brentq(f_unit, lo, hi, xtol=1e-15, rtol=1e-15)
        out.append(t)
    return _from_unit(np.unique(np.round(out, 13)), a, b) if out else np.empty(0)


def _build(fun, ranges, tol, n_max):
    """Adaptive tensor grid: returns (coef dict, single, converged, n_evaluations)."""
    dim = len(ranges)
    n, cache, converged, n_eval = N_START, {}, False, 0
    while True:
        t = chebpts2(n)
        grids = np.meshgrid(*([t] * dim), indexing="ij")
        pts = np.stack([_from_unit(g, *ranges[d]) for d, g in enumerate(grids)], axis=-1).reshape(-1, dim)
        # Nested grids: point j of degree n is point j*(M/n) of degree M (M = 2**20).
        ids = np.arange(n + 1) * (2 ** 20 // n)
        keys = np.stack(np.meshgrid(*([ids] * dim), indexing="ij"), axis=-1).reshape(-1, dim)
        key_t = [tuple(k) for k in keys.tolist()]
        new = [i for i, k in enumerate(key_t) if k not in cache]
        if new:
            vals, single = _as_dict(fun(pts[new]), len(new))
            n_eval += len(new)
            for j, i in enumerate(new):
                cache[key_t[i]] = {k: v[j] for k, v in vals.items()}
        names = list(next(iter(cache.values())))
        coefs = {}
        for k in names:
            v = np.array([cache[key][k] for key in key_t]).reshape([n + 1] * dim)
            coefs[k] = vals2coeffs(v, axes=tuple(range(dim)))
        converged = all(_tail_small(c, ax, tol) for c in coefs.values() for ax in range(dim))
        if converged or 2 * n > n_max:
            return {k: _chop(c, tol) for k, c in coefs.items()}, single, converged, n_eval
        n *= 2


def chebfun1(fun: Callable, a: float, b: float, tol: float = DEFAULT_TOL, n_max: int = 512):
    """1-D proxy (or dict of proxies) of batched ``fun(X (N, 1))`` on [a, b]."""
    rng = _check_range(a, b, "x")
    coefs, single, conv, n_eval = _build(fun, [rng], tol, n_max)
    res = {k: Cheb1(c, rng, conv, n_eval) for k, c in coefs.items()}
    return res["f"] if single else res


@dataclass
class Cheb2:
    """2-D Chebyshev proxy on [ax, bx] x [ay, by]; coef[i, j] multiplies T_i(x) T_j(y)."""

    coef: np.ndarray
    domain: tuple[tuple[float, float], tuple[float, float]]
    converged: bool = True
    n_evaluations: int = 0

    def __call__(self, x, y):
        (ax, bx), (ay, by) = self.domain
        return C.chebval2d(_to_unit(x, ax, bx), _to_unit(y, ay, by), self.coef)

    def grid(self, nx: int = 201, ny: int = 201):
        """Values on a uniform nx-by-ny grid: (xs, ys, F[ix, iy])."""
        (ax, bx), (ay, by) = self.domain
        xs, ys = np.linspace(ax, bx, nx), np.linspace(ay, by, ny)
        return xs, ys, C.chebgrid2d(_to_unit(xs, ax, bx), _to_unit(ys, ay, by), self.coef)

    def deriv(self, dx: int = 0, dy: int = 0) -> "Cheb2":
        (ax, bx), (ay, by) = self.domain
        c = self.coef
        if dx:
            c = C.chebder(c, dx, scl=2.0 / (bx - ax), axis=0) if c.shape[0] > dx else np.zeros((1, c.shape[1]))
        if dy:
            c = C.chebder(c, dy, scl=2.0 / (by - ay), axis=1) if c.shape[1] > dy else np.zeros((c.shape[0], 1))
        return Cheb2(c, self.domain, self.converged)

    def restrict(self, x=None, y=None) -> Cheb1:
        """1-D proxy along a line x = const (function of y) or y = const (function of x)."""
        (ax, bx), (ay, by) = self.domain
        if (x is None) == (y is None):
            raise ValueError("restrict needs exactly one of x, y")
        if x is not None:
            return Cheb1(C.chebval(_to_unit(x, ax, bx), self.coef), (ay, by))
        return Cheb1(C.chebval(_to_unit(y, ay, by), self.coef.T), (ax, bx))

    def zero_contour(self, n_lines: int = 101) -> np.ndarray:
        """Points (K, 2) on the zero contour: roots of the proxy along many x- and y-lines."""
        (ax, bx), (ay, by) = self.domain
        pts = []
        for x in np.linspace(ax, bx, n_lines):
            pts += [(x, y) for y in self.restrict(x=x).roots()]
        for y in np.linspace(ay, by, n_lines):
            pts += [(x, y) for x in self.restrict(y=y).roots()]
        return np.array(pts, dtype=float).reshape(-1, 2)

    def minimum(self, constraints: list["Cheb2"] = (), n_dense: int = 201,
                n_starts: int = 5, n_lines: int = 41):
        """Global minimum (x, y, f) of the proxy, optionally s.t. every ``constraints`` proxy <= 0.

        Dense evaluation of the proxies, candidates on the constraint zero contours,
        then a local polish (L-BFGS-B, or SLSQP with constraints) from the best few.
        Returns None if no feasible point is found.
        """
        (ax, bx), (ay, by) = self.domain
        xs, ys, F = self.grid(n_dense, n_dense)
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        cand = np.stack([X.ravel(), Y.ravel()], axis=1)
        for g in constraints:
            cand = np.concatenate([cand, g.zero_contour(n_lines)])
        fc = self(cand[:, 0], cand[:, 1])
        gtol = [1e-12 * max(np.max(np.abs(g.coef)), 1e-300) for g in constraints]
        feas = np.ones(len(cand), dtype=bool)
        for g, tg in zip(constraints, gtol):
            feas &= g(cand[:, 0], cand[:, 1]) <= tg
        scale_f = max(np.ptp(F), np.max(np.abs(F)), 1e-300)
        if not feas.any():
            return None
        order = np.flatnonzero(feas)[np.argsort(fc[feas])]
        chosen = []  # the best candidates, each 5 % of the box away from the others
        span = np.array([bx - ax, by - ay])
        for i in order:
            if all(np.max(np.abs(cand[i] - cand[j]) / span) > 0.05 for j in chosen):
                chosen.append(i)
            if len(chosen) >= n_starts:
                break
        best = (cand[order[0]], fc[order[0]])
        gx, gy = self.deriv(1, 0), self.deriv(0, 1)

        def obj(p):
            return float(self(p[0], p[1])) / scale_f

        def jac(p):
            return np.array([float(gx(p[0], p[1])), float(gy(p[0], p[1]))]) / scale_f

        cons = [{"type": "ineq", "fun": (lambda p, g=g: -float(g(p[0], p[1]))),
                 "jac": (lambda p, g=g: -np.array([float(g.deriv(1, 0)(p[0], p[1])),
                                                   float(g.deriv(0, 1)(p[0], p[1]))]))}
                for g in constraints]
        bounds = [(ax, bx), (ay, by)]
        for p0 in cand[chosen]:
            method = "SLSQP" if cons else "L-BFGS-B"
            opts = {"ftol": 1e-15, "maxiter": 200} if cons else {"ftol": 1e-15, "gtol": 1e-13, "maxiter": 500}
            r = minimize(obj, p0, jac=jac, bounds=bounds, constraints=cons, method=method, options=opts)
            p = np.clip(r.x, [ax, ay], [bx, by])
            fp = float(self(p[0], p[1]))
            ok = all(float(g(p[0], p[1])) <= tg for g, tg in zip(constraints, gtol))
            if ok and fp < best[1]:
                best = (p, fp)
        return float(best[0][0]), float(best[0][1]), float(best[1])


def chebfun2(fun: Callable, x_range, y_range, tol: float = DEFAULT_TOL, n_max: int = 64):
    """2-D proxy (or dict of proxies) of batched ``fun(X (N, 2))`` on x_range x y_range."""
    rx, ry = _check_range(*x_range, "x"), _check_range(*y_range, "y")
    coefs, single, conv, n_eval = _build(fun, [rx, ry], tol, n_max)
    res = {k: Cheb2(c, (rx, ry), conv, n_eval) for k, c in coefs.items()}
    return res["f"] if single else res


def on_plane(batch_fun: Callable, x0, i: int, j: int) -> Callable:
    """Batch function of (x_i, x_j) with the other variables of x0 fixed."""
    x0 = np.asarray(x0, dtype=float)

    def f2(P):
        X = np.tile(x0, (P.shape[0], 1))
        X[:, i], X[:, j] = P[:, 0], P[:, 1]
        return batch_fun(X)
    return f2

