"""MDF and IDF formulations: batched objective/constraint functions for the optimisers.

Both formulations expose ``evaluate_batch(X) -> (f (N,), g (N, m), h (N, p))`` (f is the
objective to MINIMISE: the quantity, or its negation when the problem maximises) on
physical optimiser variables, with g <= 0 feasible and h = 0 the IDF consistency
equalities (p = 0 for MDF), and scaled scalar helpers for scipy
(``fun``/``jac``/``ineq``/``ineq_jac``/``eq``/``eq_jac`` on u = (x - offset) / scale).

Gradients (``derivatives: fd``) are finite differences whose whole stencil (x and its n perturbed
points) is ONE batch, i.e. one request per graph wave. Every evaluated row is
cached, so scipy's separate fun/jac/constraint calls at one x cost nothing extra.

A failed point (a discipline error, NaN, an unconverged loop) gets objective
``FAIL_OBJECTIVE`` and every constraint ``FAIL_CONSTRAINT`` (violated); in a
stencil, a failed perturbed point of a good base point gives a zero derivative
in that direction (counted in ``fd_failures``) for the optimiser; ``unknown_derivatives`` names
those directions, so the first-order check never takes such a zero for a stationary point. With
assembled derivatives (below) they are the variables whose totals use a partial that failed.

With ``derivatives: analytic`` the gradient at a point is assembled from the disciplines'
partials instead (derivatives.py): one analysis of the point asking every discipline for its
analytic partials, one wave of per-discipline finite differences for the disciplines that
have none, then the chain rule / coupled linear solve (MDF) or the partials themselves (IDF).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bev_mdo import interrupts
from bev_mdo.mdo import first_order
from bev_mdo.mdo.derivatives import constraint_jacobian, fd_partials, idf_totals, mdf_totals, unknown_variables
from bev_mdo.mdo.discipline import first_error_line
from bev_mdo.mdo.evaluator import DisciplinesLost, Evaluator, unresponsive
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.mda import MDA, MDAResult
from bev_mdo.mdo.problem import Problem
from bev_mdo.models.common import is_number, text_hint

FAIL_OBJECTIVE = 1.0e10
ANALYSED_ROWS = 4096  # MDF: the full analyses kept of the most recent rows
FAIL_CONSTRAINT = 1.0
FD_SCHEMES = ("forward", "central")
DERIVATIVES = ("auto", "analytic", "fd")


class Formulation:
    """Common machinery: scaling, row cache, batched finite-difference stencils."""

    name = ""
    speculative_gradients = False  # set by gradient-based optimisers: evaluate a new point with its stencil
    stop_on_lost = False  # set while an optimiser runs (driver): a discipline declared unresponsive stops it

    def __init__(self, problem: Problem, evaluator: Evaluator, *, fd_step: float = 1e-6,
                 fd_scheme: str = "forward", eq_tolerance: float = 1e-6, cache_size: int = 50_000,
                 derivatives: str = "fd"):
        if derivatives not in ("analytic", "fd"):
            raise ValueError(f"optimizer.derivatives {derivatives!r} is unknown; allowed: {', '.join(DERIVATIVES)}")
        self.derivatives = derivatives
        self._want_partials = False
        if not is_number(fd_step) or not 0 < fd_step < 0.1:  # 'x' was a TypeError (exit 7)
            raise ValueError(f"optimizer.fd_step {fd_step!r} must be in (0, 0.1) (scaled units){text_hint(fd_step)}")
        if fd_scheme not in FD_SCHEMES:
            raise ValueError(f"optimizer.fd_scheme {fd_scheme!r} is unknown; allowed: {', '.join(FD_SCHEMES)}")
        self.problem, self.evaluator = problem, evaluator
        self.fd_step, self.fd_scheme, self.eq_tolerance = float(fd_step), fd_scheme, float(eq_tolerance)
        self.cache_size = int(cache_size)
        self._cache: dict[bytes, tuple[float, np.ndarray, np.ndarray, bool, str, np.ndarray]] = {}  # f g h ok error y
        self._grad: tuple[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._unknown: tuple[bytes, list[str]] | None = None  # u -> variables whose derivative failed there
        self._failed_partials: set[tuple[str, str]] = set()  # (output, input) that failed in the last assembly
        self.n_points = 0      # rows actually evaluated
        self.n_batches = 0     # evaluate_batch calls that evaluated something
        self.n_gradients = 0
        self.fd_failures = 0
        self.failures, self.first_failure = 0, ""  # points that gave no value, the first one's error line
        self.ineq_labels = problem.constraint_labels
        self.eq_labels: list[str] = []
        self._u_seen: dict[bytes, np.ndarray] = {}  # physical row -> the scaled u the optimiser asked for
        # subclasses set: var_names, lower, upper, offset, scale, x0

    # ------------------------------------------------------------ scaling
    @property
    def n(self) -> int:
        return len(self.var_names)

    def to_u(self, x: np.ndarray) -> np.ndarray:
        return (np.asarray(x, dtype=float) - self.offset) / self.scale

    def to_x(self, u: np.ndarray) -> np.ndarray:
        return self.offset + self.scale * np.asarray(u, dtype=float)

    @property
    def u_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.to_u(self.lower), self.to_u(self.upper)

    # ------------------------------------------------------------ batches
    def _evaluate_rows(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, list[str]]:
        """(f (N,), constraint outputs y (N, m), h (N, p), ok (N,), errors) of physical rows X."""
        raise NotImplementedError

    def evaluate_batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(f (N,), g (N, m), h (N, p)) at physical rows X (N, n); cached rows are not re-evaluated."""
        return self._batch(X)[:3]

    def constraint_outputs(self, X: np.ndarray) -> np.ndarray:
        """The constrained outputs y (N, m) in their own units at physical rows X (g = sign (y - bound) /
        scale). Differences of y keep digits that differences of g lose when a bound is far from y."""
        return self._batch(X)[3]

    def _batch(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        if X.shape[1] != self.n:
            raise ValueError(f"design batch has {X.shape[1]} columns, expected {self.n} columns ({self.var_names})")
        keys = [row.tobytes() for row in X]
        todo = list(dict.fromkeys(k for k in keys if k not in self._cache))
        interrupts.check()  # a SIGINT or SIGTERM that code below swallowed stops the run here (every optimiser)
        if self.stop_on_lost and (lost := unresponsive(self.evaluator)):
            raise DisciplinesLost(lost)  # so does a discipline that stopped answering (driver.run_until_lost)
        if todo:
            rows = np.array([np.frombuffer(k) for k in todo])
            f, y, h, ok, err = self._evaluate_rows(rows)
            g = self.problem.normalised(y)
            if self.problem.maximize:  # the optimisers minimise: -f (the driver reports f itself)
                f = -np.asarray(f, dtype=float)
            ok = ok & np.isfinite(f) & np.isfinite(g).all(axis=1) & np.isfinite(h).all(axis=1)
            self.n_points += len(todo)
            self.n_batches += 1
            bound, sign, scale = self.problem.g_terms()
            y_failed = bound + sign * scale * FAIL_CONSTRAINT  # the y whose g is FAIL_CONSTRAINT
            for i, k in enumerate(todo):
                if ok[i]:
                    self._cache[k] = (float(f[i]), g[i].copy(), h[i].copy(), True, "", y[i].copy())
                else:
                    self.failures += 1
                    self.first_failure = self.first_failure or first_error_line(err[i] or "failed")
                    self._cache[k] = (FAIL_OBJECTIVE, np.full(g.shape[1], FAIL_CONSTRAINT),
                                      np.full(h.shape[1], FAIL_CONSTRAINT), False, err[i] or "failed", y_failed)
        got = [self._cache[k] for k in keys]
        for k in dict.fromkeys(keys):  # least recently used first out: this batch's rows go to the end
            self._cache[k] = self._cache.pop(k)
        while len(self._cache) > self.cache_size:  # (after the look-up: a batch larger than the cache is served)
            self._cache.pop(next(iter(self._cache)))
        m = len(self.ineq_labels)
        f = np.array([c[0] for c in got])
        g = np.array([c[1] for c in got]).reshape(len(keys), m)
        h = np.array([c[2] for c in got]).reshape(len(keys), len(self.eq_labels))
        y = np.array([c[5] for c in got]).reshape(len(keys), m)
        return f, g, h, y

    def status(self, x: np.ndarray) -> tuple[bool, str]:
        """(ok, error text) of an evaluated physical point."""
        c = self._cache.get(np.asarray(x, dtype=float).tobytes())
        return (c[3], c[4]) if c else (False, "not evaluated")

    def failed_rows(self, X: np.ndarray) -> np.ndarray:
        """(N,) bool: which evaluated physical rows of X failed (a row not evaluated counts as failed)."""
        return np.array([not self.status(x)[0] for x in np.atleast_2d(np.asarray(X, dtype=float))], dtype=bool)

    def batch_fun(self, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(f, g) with equalities folded in as |h| - eq_tolerance <= 0, for inequality-only optimisers."""
        f, g, h = self.evaluate_batch(X)
        return f, np.hstack([g, np.abs(h) - self.eq_tolerance])

    # ------------------------------------------------------------ scalar helpers (scaled u)
    def u_of(self, x: np.ndarray) -> np.ndarray:
        """The scaled u an optimiser evaluated at the physical point ``x`` (bit for bit, so its cached
        rows and gradient are reused), else ``to_u(x)``."""
        x = np.asarray(x, dtype=float)
        u = self._u_seen.get(x.tobytes())
        return u.copy() if u is not None else self.to_u(x)

    def bound_violation(self, x: np.ndarray) -> float:
        """How far the physical point ``x`` lies outside its bounds (first_order.bound_violation, in
        scaled units); 0 inside. A point outside the bounds is never feasible."""
        return first_order.bound_violation(self.to_u(x), *self.u_bounds)

    def best_seen(self, max_violation: float) -> np.ndarray | None:
        """The scaled u of the lowest objective among the points an optimiser evaluated whose largest
        violation (g, |h| and the bounds) is within ``max_violation``; None if there is none."""
        best, best_f = None, np.inf
        for key, u in self._u_seen.items():
            c = self._cache.get(key)
            if c is None or not c[3]:
                continue
            viol = max(float(np.max(c[1], initial=0.0)), float(np.max(np.abs(c[2]), initial=0.0)),
                       self.bound_violation(np.frombuffer(key)))
            if viol <= max_violation and c[0] < best_f:
                best, best_f = u.copy(), c[0]
        return best

    def values(self, u: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
        u = np.asarray(u, dtype=float)
        self._u_seen[self.to_x(u).tobytes()] = u.copy()
        while len(self._u_seen) > 4096:
            self._u_seen.pop(next(iter(self._u_seen)))
        if self.speculative_gradients and self.to_x(u).tobytes() not in self._cache:
            # A gradient-based optimiser asks for the gradient at nearly every point it
            # evaluates: send the point and its FD stencil as ONE batch (one request wave)
            # instead of two. The values are identical; only the batching changes.
            self.gradients(u)
        f, g, h = self.evaluate_batch(self.to_x(u)[None, :])
        return float(f[0]), g[0], h[0]

    def fun(self, u: np.ndarray) -> float:
        return self.values(u)[0] / self.problem.objective_scale

    def ineq(self, u: np.ndarray) -> np.ndarray:
        """scipy convention: >= 0 feasible."""
        return -self.values(u)[1]

    def eq(self, u: np.ndarray) -> np.ndarray:
        return self.values(u)[2]

    def jac(self, u: np.ndarray) -> np.ndarray:
        return self.gradients(u)[0] / self.problem.objective_scale

    def ineq_jac(self, u: np.ndarray) -> np.ndarray:
        return -self.gradients(u)[1]

    def eq_jac(self, u: np.ndarray) -> np.ndarray:
        return self.gradients(u)[2]

    def gradients(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(df (n,), dg (m, n), dh (p, n)) w.r.t. u; the whole stencil is one batch."""
        u = np.asarray(u, dtype=float)
        key = u.tobytes()
        if self._grad is not None and self._grad[0] == key:
            return self._grad[1]
        self.n_gradients += 1
        if self.derivatives == "analytic":
            self._failed_partials = set()
            out = self._assembled(u)
            self._grad = (key, out)
            # a discipline's failed finite-difference partial: the variables whose totals it enters; the
            # point itself failed when evaluated again for its partials: every variable
            self._unknown = (key, self._unknown_variables(self._failed_partials) if self.status(self.to_x(u))[0]
                             else list(self.var_names))
            return out
        lo, hi = self.u_bounds
        hstep = self.fd_step
        fwd = np.where(u + hstep <= hi, hstep, -hstep)
        eye = np.eye(self.n)
        if self.fd_scheme == "central":
            both = (u - hstep >= lo) & (u + hstep <= hi)
            plus = u + eye * np.where(both, hstep, fwd)[:, None]
            minus = np.where(both[:, None], u - eye * hstep, u[None, :])
            U = np.vstack([u[None, :], plus, minus])
            denom = np.where(both, 2 * hstep, fwd)
        else:
            plus = u + eye * fwd[:, None]
            U = np.vstack([u[None, :], plus])
            denom = fwd
        f, _, h, y = self._batch(self.to_x(U))
        ok = np.array([self.status(x)[0] for x in self.to_x(U)])
        n = self.n
        # Differences of the constrained outputs y, not of g = sign (y - bound) / scale: g rounds y to
        # eps |bound|, which is most of a difference when the bound is far from y (w <= 1e9, w ~ 80).
        V = np.column_stack([f, y, h])  # (rows, 1 + m + p)
        if self.fd_scheme == "central":
            lower_rows = np.where(both[:, None], V[1 + n:], V[0][None, :])
            lower_ok = np.where(both, ok[1 + n:], ok[0])
            D = (V[1:1 + n] - lower_rows) / denom[:, None]
            good = ok[1:1 + n] & lower_ok
        else:
            D = (V[1:] - V[0][None, :]) / denom[:, None]
            good = ok[1:]
        self._unknown = (key, [] if ok[0] else list(self.var_names))  # no derivative at all about a failed point
        if ok[0] and not good.all():
            self.fd_failures += int((~good).sum())
            D[~good] = 0.0
            self._unknown = (key, [self.var_names[j] for j in np.flatnonzero(~good)])
        D = D.T  # (1 + m + p, n)
        m = y.shape[1]
        _, sign, scale = self.problem.g_terms()
        out = (D[0], D[1:1 + m] * (sign / scale)[:, None], D[1 + m:])
        self._grad = (key, out)
        return out

    def fd_gradients(self, u: np.ndarray, step: float) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], list[str]]:
        """(``gradients(u)`` by central differences of scaled step ``step`` whatever ``derivatives`` says (one
        batch), the variables without one): what an optimum reached on the disciplines' analytic partials is
        checked against. The run's own settings, counts and derivatives are left as they were."""
        kept = (self.derivatives, self.fd_scheme, self.fd_step, self._unknown, self.fd_failures, self.n_gradients)
        self.derivatives, self.fd_scheme, self.fd_step, self._grad = "fd", "central", step, None
        try:
            return self.gradients(u), self.unknown_derivatives(u)
        finally:
            (self.derivatives, self.fd_scheme, self.fd_step, self._unknown, self.fd_failures, self.n_gradients) = kept
            self._grad = None

    def unknown_derivatives(self, u: np.ndarray) -> list[str]:
        """The variables in which ``gradients(u)`` (taken before) has no derivative: a finite-difference
        point failed and the optimiser was given 0 there."""
        key = np.asarray(u, dtype=float).tobytes()
        return list(self._unknown[1]) if self._unknown is not None and self._unknown[0] == key else []

    # ------------------------------------------------------------ assembled derivatives
    @property
    def mda_evaluations(self) -> int:
        return self.mda.n_evaluations

    def _assembled(self, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(df (n,), dg (m, n), dh (p, n)) w.r.t. u from discipline partials."""
        x = self.to_x(u)
        self._cache.pop(x.tobytes(), None)  # (re-)evaluate x asking the disciplines for their partials
        self._want_partials = True
        try:
            self.evaluate_batch(x[None, :])
        finally:
            self._want_partials = False
        m, p = len(self.ineq_labels), len(self.eq_labels)
        if not self.status(x)[0]:  # a failed point has no derivative
            return np.zeros(self.n), np.zeros((m, self.n)), np.zeros((p, self.n))
        df, dg, dh = self._totals()
        if self.problem.maximize:  # the optimisers minimise -f (evaluate_batch negates f the same way)
            df = -df
        return df * self.scale, dg * self.scale[None, :], dh * self.scale[None, :]

    def _fd_rest(self, part: dict, values: dict, base_needed=(), base_outputs=None) -> dict:
        missing = [d for d in self.mda.specs if d not in part]
        fdp, failed = fd_partials(self.evaluator, self.mda.specs, missing, values, 1, self.fd_step,
                                  self.fd_scheme == "central", base_needed, base_outputs)
        self.fd_failures += sum(failed.values())
        self._failed_partials.update(failed)
        return {**part, **fdp}

    def _quantities(self) -> list[str]:
        """The outputs the optimiser sees: the objective and the constrained quantities."""
        return [self.problem.objective] + [name for name, *_ in self.problem.constraint_rows]


class MDF(Formulation):
    """Multidisciplinary feasible: optimiser over design variables, a full MDA per point."""

    name = "mdf"

    def __init__(self, problem: Problem, evaluator: Evaluator, mda: MDA, **kw):
        super().__init__(problem, evaluator, **kw)
        self.mda = mda
        self.var_names = problem.names
        self.lower, self.upper = problem.array("lower"), problem.array("upper")
        self.offset, self.scale = self.lower.copy(), problem.array("scale")
        self.x0 = problem.x0()
        self._analysed: dict[bytes, tuple[dict[str, float], bool, str, int]] = {}

    def analyse(self, X: np.ndarray) -> MDAResult:
        X = np.atleast_2d(np.asarray(X, dtype=float))
        inputs = {n: X[:, j] for j, n in enumerate(self.var_names)}
        for k, v in self.problem.parameters.items():
            inputs[k] = np.full(len(X), v)
        if self._want_partials:
            self._last = self.mda.run(inputs, partials=True)
            return self._last
        return self.mda.run(inputs)

    def _totals(self):
        res = self._last
        loops = {m for c in self.mda.graph.cycles for m in c}
        values = {k: v[:1] for k, v in res.values.items()}
        part = self._fd_rest(dict(res.partials or {}), values, loops)
        tot = mdf_totals(list(self.mda.graph.producer), self.var_names, part, 1)
        df = tot[self.problem.objective][0]
        dg = constraint_jacobian(self.problem, tot, self.var_names, 1)[0]
        return df, dg, np.zeros((0, self.n))

    def _unknown_variables(self, failed) -> list[str]:
        return unknown_variables(failed, self.var_names, self._quantities(), self.mda.specs)

    def analysed(self, x: np.ndarray, again: bool = False) -> tuple[dict[str, float], bool, str, int] | None:
        """(every MDA variable, ok, error, loop iterations) of a recently analysed point, or None; ``again``:
        a point that has left the recent rows (ANALYSED_ROWS) is analysed once more."""
        x = np.asarray(x, dtype=float)
        if again and x.tobytes() not in self._analysed:
            self._evaluate_rows(x[None, :])
        return self._analysed.get(x.tobytes())

    def _evaluate_rows(self, X):
        res = self.analyse(X)
        # Keep the full analysis of the recent rows: the final report of a run reads it
        # instead of analysing the optimum once more.
        for i, row in enumerate(X):
            self._analysed[row.tobytes()] = ({k: float(v[i]) for k, v in res.values.items()}, bool(res.ok[i]),
                                             res.messages[i], int(res.iterations[i]))
        while len(self._analysed) > ANALYSED_ROWS:
            self._analysed.pop(next(iter(self._analysed)))
        f = res.values[self.problem.objective]
        return f, self.problem.constraint_outputs(res.values), np.zeros((len(X), 0)), res.ok, res.messages


class IDF(Formulation):
    """Individual discipline feasible: coupling variables become optimiser variables,
    with equalities (target - computed) / scale = 0; all disciplines run in ONE wave."""

    name = "idf"

    def __init__(self, problem: Problem, evaluator: Evaluator, mda: MDA, **kw):
        super().__init__(problem, evaluator, **kw)
        self.mda = mda  # used once, to start from a consistent coupling point
        self.disciplines: Sequence[str] = list(mda.specs)
        graph = CouplingGraph((s.name, s.inputs, s.outputs) for s in mda.specs.values())
        self.couplings = [v for v in graph.couplings if v not in problem.names]
        dv_names = problem.names
        y0 = self._consistent(problem.x0())
        self.var_names = dv_names + self.couplings
        self.lower = np.concatenate([problem.array("lower"), [problem.coupling_bound(c)[0] for c in self.couplings]])
        self.upper = np.concatenate([problem.array("upper"), [problem.coupling_bound(c)[1] for c in self.couplings]])
        # Couplings to order one like the design variables: from their bounds where both are given
        # (OpenMDAO's ref0/ref), else from their value at the start (floored at 1).
        lo_c, hi_c = self.lower[len(dv_names):], self.upper[len(dv_names):]
        bounded = np.isfinite(lo_c) & np.isfinite(hi_c)
        self.coupling_scale = np.where(bounded, hi_c - lo_c, np.maximum(np.abs(y0), 1.0))
        self.offset = np.concatenate([problem.array("lower"), np.where(bounded, lo_c, 0.0)])
        self.scale = np.concatenate([problem.array("scale"), self.coupling_scale])
        self.x0 = np.concatenate([problem.x0(), np.clip(y0, self.lower[len(dv_names):], self.upper[len(dv_names):])])
        self.eq_labels = [f"{c} consistency" for c in self.couplings]

    def _consistent(self, design: np.ndarray) -> np.ndarray:
        """The couplings an MDA gives at ``design`` (their guesses where it fails)."""
        problem = self.problem
        start = self.mda.run({**{n: [x] for n, x in zip(problem.names, design)},
                              **{k: [v] for k, v in problem.parameters.items()}})
        return np.array([start.values[c][0] if start.ok[0] else problem.coupling_guess(c) for c in self.couplings])

    def start_at(self, design: np.ndarray) -> None:
        """Start from ``design`` with the couplings consistent there, as the config's initial design
        starts: a start given by the caller (``x0``: resume, ``--starts``) is not made infeasible by
        couplings computed at another point."""
        n_dv = len(self.problem.names)
        y0 = self._consistent(np.asarray(design, dtype=float))
        self.x0 = np.concatenate([design, np.clip(y0, self.lower[n_dv:], self.upper[n_dv:])])

    def _evaluate_rows(self, X):
        N = len(X)
        cols = {n: X[:, j] for j, n in enumerate(self.var_names)}
        for k, v in self.problem.parameters.items():
            cols[k] = np.full(N, v)
        specs = self.mda.specs
        calls = [(name, self.mda.calls.inputs(name, cols, slice(None))) for name in self.disciplines]
        if self._want_partials:
            results = self.evaluator.evaluate(calls, partials=True)
        else:
            results = self.evaluator.evaluate(calls)
        out: dict[str, np.ndarray] = dict(cols)
        ok = np.ones(N, dtype=bool)
        errors = [""] * N
        for (name, _), res in zip(calls, results):
            out.update({k: np.asarray(v, dtype=float) for k, v in res.outputs.items() if k in specs[name].outputs})
            for i in np.flatnonzero(~np.asarray(res.ok)):
                if ok[i]:
                    ok[i], errors[i] = False, res.message(int(i), int(i), name)
        f = out[self.problem.objective]
        y = self.problem.constraint_outputs(out)
        n_dv = len(self.problem.names)
        h = np.column_stack([(X[:, n_dv + k] - out[c]) / self.coupling_scale[k]
                             for k, c in enumerate(self.couplings)]) if self.couplings else np.zeros((N, 0))
        if self._want_partials:
            self._last = (cols, out, {name: res.extra["partials"] for (name, _), res in zip(calls, results)
                                      if "partials" in res.extra})
        return f, y, h, ok, errors

    def _unknown_variables(self, failed) -> list[str]:
        return unknown_variables(failed, self.var_names, self._quantities() + self.couplings, {})

    def _totals(self):
        cols, out, part = self._last
        # the disciplines ran at the couplings' targets (cols), not at what the others computed (out):
        # their finite differences step from the targets, from the outputs computed there
        inputs = {k: np.asarray(v)[:1] for k, v in cols.items()}
        part = self._fd_rest(dict(part), inputs, base_outputs={k: np.asarray(v)[:1] for k, v in out.items()})
        outputs = [v for s in self.mda.specs.values() for v in s.outputs]
        tot = idf_totals(outputs, self.var_names, part, 1)
        df = tot[self.problem.objective][0]
        dg = constraint_jacobian(self.problem, tot, self.var_names, 1)[0]
        n_dv = len(self.problem.names)
        dh = np.zeros((len(self.couplings), self.n))
        for k, c in enumerate(self.couplings):
            dh[k] = -tot[c][0]
            dh[k, n_dv + k] += 1.0
            dh[k] /= self.coupling_scale[k]
        return df, dg, dh


FORMULATIONS = {"mdf": MDF, "idf": IDF}
