"""Normalised first- and second-order sensitivities (thesis eqs 5-3..5-5) by batched FD.

``fun(X)`` takes X of shape (N, n) (columns in the order of ``point``) and returns a
dict of output arrays of shape (N,) (or one (N,) array, named ``"f"``). Every
stencil is ONE call of ``fun``; steps h and 2h share that call so that Richardson
extrapolation gives both the value and an error estimate.

    S_i    = (x_i / f) * df/dx_i                     (eq 5-4)
    S'_ij  = (x_i * x_j / f) * d2f/dx_i dx_j         (eq 5-5, diagonal included)

Coupling labels for |S'_ij| (the thesis gives none numerically; chosen so that the
Fig 5-3 values map to the Fig 5-3 labels): NC < 0.05 <= MC < 0.5 <= SC < 0.8 <= VSC.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np

BatchFun = Callable[[np.ndarray], "Mapping[str, np.ndarray] | np.ndarray"]

COUPLING_THRESHOLDS = (("NC", 0.05), ("MC", 0.5), ("SC", 0.8))  # label if |s| < bound
REL_STEP_FIRST = 1e-4
REL_STEP_SECOND = 1e-3
REL_STEP_MAX = 0.5  # rel_step is in (0, REL_STEP_MAX)
COMPLEX_STEP = 1e-20
_CENTRAL = np.array([-1.0, 0.0, 1.0])
_ONE_SIDED = np.array([0.0, 1.0, 2.0, 3.0])


def coupling_label(value: float) -> str:
    """NC / MC / SC / VSC for a normalised second-order value (module docstring)."""
    a = abs(float(value))
    if not np.isfinite(a):  # undefined (an output that is 0 at the point)
        return ""
    for label, bound in COUPLING_THRESHOLDS:
        if a < bound:
            return label
    return "VSC"


@dataclass
class Sensitivities:
    """Result: normalised and raw derivatives per output, step and error estimates."""

    names: tuple[str, ...]                      # variables differentiated (wrt)
    point: dict[str, float]                     # full point
    values: dict[str, float]                    # f at the point, per output
    gradient: dict[str, np.ndarray]             # raw df/dx, (n,)
    first: dict[str, np.ndarray]                # normalised eq 5-4, (n,)
    first_error: dict[str, np.ndarray]          # error estimate of ``first`` (Richardson's; half a kink's jump)
    step: np.ndarray                            # absolute step h per wrt variable
    method: str                                 # "central" / "complex" (first order)
    hessian: dict[str, np.ndarray] | None = None      # raw, (n, n)
    second: dict[str, np.ndarray] | None = None       # normalised eq 5-5, (n, n)
    second_error: dict[str, np.ndarray] | None = None  # Richardson's, at least the rounding of the stencil's values
    n_evaluations: int = 0
    n_batches: int = 0
    one_sided: tuple[str, ...] = field(default_factory=tuple)  # variables on a bound
    gradient_error: dict[str, np.ndarray] | None = None  # error estimates of the raw ``gradient`` and ``hessian``:
    hessian_error: dict[str, np.ndarray] | None = None   # what marks an output's rows where its S is undefined

    @property
    def undefined(self) -> list[str]:
        """The outputs whose S is undefined (f = 0 at the point, or 0 but for rounding): NaN in ``first``."""
        return [k for k, v in self.first.items() if np.isnan(v).all() and np.isfinite(self.gradient[k]).all()]

    def labels(self, output: str) -> np.ndarray:
        """Coupling labels (object array (n, n)) of the second-order matrix of ``output``."""
        if self.second is None:
            raise ValueError("second-order sensitivities were not computed (order=1)")
        m = self.second[_known(output, self.second, "output")]
        return np.vectorize(coupling_label, otypes=[object])(m)


def _known(name: str, known: Sequence[str], what: str) -> str:
    if name not in known:
        raise ValueError(f"unknown {what} {name!r} (known: {', '.join(known)})")
    return name


def _weights(offsets: np.ndarray, order: int) -> np.ndarray:
    """FD weights on integer ``offsets`` for the derivative of ``order`` (unit step)."""
    m = len(offsets)
    a = np.vander(offsets, m, increasing=True).T  # a[p, k] = offsets[k]**p
    rhs = np.zeros(m)
    rhs[order] = float(np.prod(np.arange(1, order + 1)))
    return np.linalg.solve(a, rhs)


def _call(fun: BatchFun, X: np.ndarray) -> dict[str, np.ndarray]:
    out = fun(X)
    if not isinstance(out, Mapping):
        out = {"f": out}
    res = {}
    for k, v in out.items():
        v = np.asarray(v)
        if v.shape != (X.shape[0],):
            raise ValueError(f"output {k!r} has shape {v.shape}, expected ({X.shape[0]},)")
        res[str(k)] = v
    return res


def _prepare(point, wrt, bounds, rel_step):
    if not point:
        raise ValueError("point is empty: give at least one variable")
    all_names = tuple(point)
    x0 = np.array([float(point[k]) for k in all_names])
    if not np.all(np.isfinite(x0)):
        raise ValueError(f"point has non-finite values: {dict(point)}")
    wrt = tuple(all_names if wrt is None else wrt)
    if not wrt:
        raise ValueError("wrt is empty: name at least one variable")
    for k in wrt:
        _known(k, all_names, "variable")
    idx = np.array([all_names.index(k) for k in wrt])
    lo = np.full(len(all_names), -np.inf)
    hi = np.full(len(all_names), np.inf)
    for k, (a, b) in (bounds or {}).items():
        j = all_names.index(_known(k, all_names, "bounded variable"))
        lo[j], hi[j] = float(a), float(b)
        if not lo[j] <= x0[j] <= hi[j]:
            raise ValueError(f"point {k}={x0[j]:g} is outside its bounds [{lo[j]:g}, {hi[j]:g}]")
    scale = np.where(np.isfinite(hi - lo), (hi - lo) * 0.1, 1.0)
    base = np.abs(x0[idx])
    h = rel_step * np.where(base > 0, base, np.minimum(scale[idx], 1.0))
    # Shrink h so the (2h) stencil fits inside the bounds; go one-sided on a bound.
    direction = np.zeros(len(wrt))
    for a, j in enumerate(idx):
        room_up, room_dn = hi[j] - x0[j], x0[j] - lo[j]
        if min(room_up, room_dn) >= 2 * h[a]:
            continue
        direction[a] = 1.0 if room_up >= room_dn else -1.0
        if max(room_up, room_dn) >= 6 * h[a]:
            continue
        h[a] = max(room_up, room_dn) / 6.0
        if h[a] <= 0:
            raise ValueError(f"bounds of {wrt[a]!r} leave no room for a finite-difference step")
    return all_names, x0, wrt, idx, h, direction


# |f| below this of max_i |x_i df/dx_i|: f is 0 but for rounding, |S| above 1e12 (SSBJ's active g_2 at its optimum,
# -2.1e-14 where x df/dx is 0.24, printed S = -1.1e13: rounding in terms larger than x df/dx, up to 1e4 times it)
ZERO_TO_ROUNDING = 1e-12


def _normalise(f0: float, change: float) -> float:
    """f0, or NaN where the normalised sensitivity (x/f) df/dx is undefined: f = 0, or 0 but for rounding against
    ``change`` (max_i |x_i df/dx_i|: 1.15e-14 left of a cancellation printed S = -4.5e14, unmarked). The
    derivatives stay in ``gradient`` and ``hessian``."""
    return f0 if f0 != 0 and np.isfinite(f0) and not abs(f0) < ZERO_TO_ROUNDING * change else np.nan


def sensitivities(fun: BatchFun, point: Mapping[str, float], wrt: Sequence[str] | None = None,
                  order: int = 1, bounds: Mapping[str, tuple[float, float]] | None = None,
                  rel_step: float | None = None, method: str = "central") -> Sensitivities:
    """Normalised sensitivities of every output of ``fun`` at ``point`` w.r.t. ``wrt``.

    ``method``: "central" (real FD), "complex" (complex step, first order; ``fun``
    must accept complex X) or "auto" (complex if ``fun`` supports it, else central).
    An output that is 0 at the point (or but for rounding) has NaN normalised values and its plain derivatives.
    Order 2 evaluates the whole stencil (h and 2h) in one batch.
    """
    if order not in (1, 2):
        raise ValueError(f"order must be 1 or 2, got {order!r}")
    if method not in ("central", "complex", "auto"):
        raise ValueError(f"method must be 'central', 'complex' or 'auto', got {method!r}")
    if rel_step is None:
        rel_step = REL_STEP_SECOND if order == 2 else REL_STEP_FIRST
    if not (0 < rel_step < REL_STEP_MAX):
        raise ValueError(f"rel_step must be in (0, {REL_STEP_MAX:g}), got {rel_step!r}")
    all_names, x0, wrt, idx, h, direction = _prepare(point, wrt, bounds, rel_step)
    n_eval = n_batch = 0
    grad_c = used = None
    if method in ("complex", "auto"):
        grad_c, f0c, nc = _complex_step(fun, x0, idx, method == "complex")
        if grad_c is not None:
            used, n_eval, n_batch = "complex", nc, 1
    if order == 2 or grad_c is None:
        f0, g, g_err, H, H_err, ne = _real_stencil(fun, x0, idx, h, direction, order)
        n_eval += ne
        n_batch += 1
    else:
        f0, H, H_err = f0c, None, None
    if grad_c is not None:  # the complex-step gradient is exact to rounding
        g, g_err = grad_c, {k: np.zeros(len(idx)) for k in grad_c}
    xw = x0[idx]
    first, first_err, second, second_err = {}, {}, {}, {}
    for k in f0:
        fn = _normalise(f0[k], float(np.nanmax(np.abs(g[k] * xw), initial=0.0)))
        first[k] = g[k] * xw / fn
        first_err[k] = np.abs(g_err[k] * xw / fn)
        if H is not None:
            xx = np.outer(xw, xw)
            second[k] = H[k] * xx / fn
            second_err[k] = np.abs(H_err[k] * xx / fn)
    return Sensitivities(
        names=wrt, point=dict(zip(all_names, x0.tolist())), values=dict(f0), gradient=g,
        first=first, first_error=first_err, step=h, method=used or "central",
        hessian=H, second=second if H is not None else None,
        second_error=second_err if H is not None else None,
        n_evaluations=n_eval, n_batches=n_batch,
        one_sided=tuple(w for w, d in zip(wrt, direction) if d != 0),
        gradient_error=dict(g_err), hessian_error=dict(H_err) if H is not None else None)


def _complex_step(fun, x0, idx, strict):
    n = len(idx)
    hs = COMPLEX_STEP * np.maximum(np.abs(x0[idx]), 1.0)
    X = np.tile(x0.astype(complex), (n + 1, 1))
    X[np.arange(1, n + 1), idx] += 1j * hs
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", np.exceptions.ComplexWarning)
            out = _call(fun, X)
        ok = all(np.iscomplexobj(v) and np.all(np.isfinite(v)) for v in out.values())
    except (TypeError, ValueError, np.exceptions.ComplexWarning) as exc:
        if strict:
            raise ValueError(f"complex step not supported by the model: {exc}") from None
        return None, None, 0
    if not ok:
        if strict:
            raise ValueError("complex step not supported by the model: outputs are not complex")
        return None, None, 0
    f0 = {k: float(v[0].real) for k, v in out.items()}
    grad = {k: v[1:].imag / hs for k, v in out.items()}
    return grad, f0, n + 1


def _kink_error(v: np.ndarray, points: dict, direction, h) -> np.ndarray:
    """Half the jump between the one-sided slopes either side of the point, per central variable, where the
    jump is a kink's (the same at steps h and 2h; curvature doubles it, noise rarely repeats it); 0 elsewhere.
    A kink at the point itself makes the steps h and 2h agree on the mean of its two slopes, with no
    Richardson error (a Taycan-like top speed: 0.188 printed, 0.376 one side and 0 the other)."""
    out = np.zeros(len(direction))
    for a, d in enumerate(direction):
        if d != 0:
            continue
        jump = []
        for s in (1.0, 2.0):
            right, left = (v[points[((a, s * o),)]] for o in (1.0, -1.0))
            jump.append((right - 2.0 * v[0] + left) / (s * h[a]))  # right-hand minus left-hand slope
        if jump[0] != 0.0 and 2.0 / 3.0 <= jump[1] / jump[0] <= 1.5:
            out[a] = abs(jump[0]) / 2.0
    return out


def _real_stencil(fun, x0, idx, h, direction, order):
    """One batch with steps h and 2h: gradient (and Hessian) + Richardson errors."""
    n = len(idx)
    offs = [(_CENTRAL if d == 0 else d * _ONE_SIDED) for d in direction]
    w1 = [_weights(o, 1) for o in offs]
    w2 = [_weights(o, 2) for o in offs]
    points: dict[tuple, int] = {}  # distinct stencil points (offset tuples) -> their row in the batch

    def add(shift: dict) -> int:
        return points.setdefault(tuple(sorted((a, float(o)) for a, o in shift.items() if o != 0)), len(points))

    add({})
    terms = []  # (kind, a, b, scale, [(row, weight)])
    for s in (1.0, 2.0):
        for a in range(n):
            terms.append(("g", a, a, s, [(add({a: s * o}), w) for o, w in zip(offs[a], w1[a]) if w != 0]))
            if order == 2:
                terms.append(("H", a, a, s, [(add({a: s * o}), w) for o, w in zip(offs[a], w2[a]) if w != 0]))
                for b in range(a + 1, n):
                    rows = [(add({a: s * oa, b: s * ob}), wa * wb)
                            for oa, wa in zip(offs[a], w1[a]) if wa != 0
                            for ob, wb in zip(offs[b], w1[b]) if wb != 0]
                    terms.append(("H", a, b, s, rows))
    X = np.tile(x0, (len(points), 1))
    for r, key in enumerate(points):
        for a, o in key:
            X[r, idx[a]] += o * h[a]
    out = {k: np.asarray(v, dtype=float) for k, v in _call(fun, X).items()}
    f0 = {k: float(v[0]) for k, v in out.items()}
    g, g_err, H, H_err = {}, {}, {}, {}
    eps = np.finfo(float).eps
    for k, v in out.items():
        est, ulp = {}, {}
        for kind, a, b, s, rows in terms:
            denom = (s * h[a]) * (s * h[b]) if kind == "H" else s * h[a]
            est[(kind, a, b, s)] = sum(w * v[r] for r, w in rows) / denom
            # the rounding of the values, a few ulps each (the model's own and the sum's)
            ulp[(kind, a, b, s)] = 4.0 * eps * sum(abs(w * v[r]) for r, w in rows) / abs(denom)
        gh = np.array([est[("g", a, a, 1.0)] for a in range(n)])
        g2 = np.array([est[("g", a, a, 2.0)] for a in range(n)])
        g[k], g_err[k] = gh + (gh - g2) / 3.0, np.abs(gh - g2) / 3.0
        g_err[k] = np.maximum(g_err[k], _kink_error(v, points, direction, h))
        if order == 2:
            Hh, H2, floor = np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, n))
            for a in range(n):
                for b in range(a, n):
                    Hh[a, b] = Hh[b, a] = est[("H", a, b, 1.0)]
                    H2[a, b] = H2[b, a] = est[("H", a, b, 2.0)]
                    # the rounding of the values in (4 Hh - H2) / 3: steps h and 2h can agree to the last bit
                    # on a cross term that is 0 (a Richardson error of 1e-11 beside an entry of 5e-11)
                    floor[a, b] = floor[b, a] = (4.0 * ulp[("H", a, b, 1.0)] + ulp[("H", a, b, 2.0)]) / 3.0
            H[k], H_err[k] = Hh + (Hh - H2) / 3.0, np.maximum(np.abs(Hh - H2) / 3.0, floor)
    if order == 1:
        H = H_err = None
    return f0, g, g_err, H, H_err, X.shape[0]
