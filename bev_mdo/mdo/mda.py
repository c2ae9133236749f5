"""Multidisciplinary analysis (MDA) of a batch of N design points.

An acyclic (feed-forward) graph is analysed by data flow (``flow.py``): one request for the
whole MDA when the evaluator offers it (the ROS nodes pass results from node to node), else
one ``evaluator.evaluate`` call per wave; a discipline evaluates the points its sources
evaluated. A graph with loops runs wave by wave: one call per wave holds every feed-forward
discipline of that wave. A feedback loop is
iterated by Gauss-Seidel (one call per discipline, in the loop's declared order)
or Jacobi (one call per sweep, all loop disciplines together, after one sequential
seeding pass from the torn-variable guesses), or Newton-Raphson (``newton``, below),
vectorised over the points still iterating. A point whose discipline fails, or whose loop does
not converge, gets NaN outputs, ``ok`` False and an error text; nothing raises.

Newton-Raphson (``method: newton``; OpenMDAO's NewtonSolver, GEMSEO's MDANewtonRaphson) solves
R(y) = F(y) - y = 0 over the loop's couplings y (every loop output that a loop discipline reads).
Each step evaluates ALL loop disciplines at y in ONE ``evaluate`` call (one request wave over
ROS) asking for their partials, assembles J = dF/dy per point and solves
(I - J) dy = F(y) - y (batched ``np.linalg.solve`` over the points, vector couplings as their
element columns), then y <- y + relaxation * dy. A loop discipline without analytic partials
gets a forward finite-difference Jacobian over its coupling inputs (step 1e-7 max(|y|, 1)):
its perturbed points travel in the same call, stacked after its base points (a transport that
cannot tell beforehand, ROS, learns it from the first answer and sends one extra call then).
Convergence is the Gauss-Seidel criterion applied to the fixed-point residual, max |F(y) - y| /
max(|F(y)|, 1) <= tolerance; the loop's values are then the y of that last evaluation, so the
partials of that call are exactly at the converged values and ``run(partials=True)`` needs no
extra call. Before the first step, loop couplings that are neither torn (guessed) nor given
are seeded by one sequential call per discipline producing them, in loop order.

Warm start (``warm_start``; ``auto``: on for newton only): a loop starts from the couplings its
previous MDA converged to (the first converged point of that batch; a given coupling column still
overrides), and Newton then needs no seeding call. ``tangent`` (newton) adds the first-order
prediction y_ref + (I - J)^-1 dF/dx (x - x_ref) from the Jacobian and partials of that point's
last step (plain warm start when a loop discipline has no analytic partials). Newton's converged
couplings are the fixed point to far below the tolerance from any start, so results depend on the
history only at that level; the same sequence of MDAs gives the same values bit for bit.
``fuse_downstream`` (newton): the feed-forward disciplines that read the loop's couplings ride in
every Newton step's call (``_downstream``); a point keeps their results of the step at which it
converged, which are at its reported couplings: one request wave less per MDA, one evaluation of
them per step instead of per MDA. docs/derivatives.md has the reasons and the figures.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bev_mdo.mdo.discipline import EvalResult
from bev_mdo.mdo.evaluator import Evaluator
from bev_mdo.mdo.flow import evaluate_flow
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.vectors import base_name

METHODS = ("gauss_seidel", "jacobi", "newton")
FD_STEP = 1e-7  # relative forward-difference step of a Newton Jacobian column without analytic partials


@dataclass
class MDAResult:
    """All variables of the batch (inputs and outputs, shape (N,)) and per-point status."""

    values: dict[str, np.ndarray]
    ok: np.ndarray          # bool (N,)
    errors: list[str]       # '' for a good point
    iterations: np.ndarray  # loop sweeps per point (0 for a feed-forward graph)
    partials: dict[str, dict] | None = None  # run(partials=True): discipline -> {(out, in): (N,)}
                                             # for every discipline that has analytic partials


class MDA:
    """Batched multidisciplinary analysis over an evaluator.

    ``guesses`` are starting values for loop (coupling) variables, default 1.0;
    an input column with the variable's name overrides the guess per point.
    ``n_evaluations`` counts analysed points. ``data_flow`` False analyses an acyclic graph
    wave by wave with the loop rule instead (a wave runs the points still good).
    """

    def __init__(self, evaluator: Evaluator, *, method: str = "gauss_seidel", tolerance: float = 1e-10,
                 max_iterations: int = 100, relaxation: float = 1.0,
                 guesses: Mapping[str, float] | None = None, disciplines: Sequence[str] | None = None,
                 data_flow: bool = True, warm_start: bool | str = "auto", fuse_downstream: bool = False):
        if method not in METHODS:
            raise ValueError(f"mda method {method!r} is unknown; allowed: {', '.join(METHODS)}")
        if not tolerance > 0:
            raise ValueError(f"mda tolerance {tolerance} must be > 0")
        if int(max_iterations) < 1:
            raise ValueError(f"mda max_iterations {max_iterations} must be >= 1")
        if not 0 < relaxation <= 2:
            raise ValueError(f"mda relaxation {relaxation} must be in (0, 2]")
        if not isinstance(warm_start, bool) and warm_start not in ("auto", "tangent"):
            raise ValueError(f"mda warm_start {warm_start!r} must be true, false, auto or tangent")
        if warm_start == "tangent" and method != "newton":
            raise ValueError(f"mda warm_start tangent needs method newton (the tangent comes from its Jacobian), "
                             f"not {method}")
        if not isinstance(fuse_downstream, bool):
            raise ValueError(f"mda fuse_downstream {fuse_downstream!r} must be true or false")
        self.evaluator = evaluator
        self.method, self.tolerance = method, float(tolerance)
        # auto: on for newton only (its converged couplings are exact far below the tolerance, see
        # the module docstring), off for the fixed-point methods
        self.warm_start = (method == "newton") if warm_start == "auto" else bool(warm_start)
        self.tangent = warm_start == "tangent"  # newton: first-order prediction from the warm start
        self.fuse_downstream = bool(fuse_downstream) and method == "newton"
        self._warm: dict[tuple, dict[str, float]] = {}  # loop -> converged couplings of the last MDA
        self._tangent: dict[tuple, tuple | None] = {}   # loop -> its tangent dy/dx there (tangent)
        self.max_iterations, self.relaxation = int(max_iterations), float(relaxation)
        self.guesses = dict(guesses or {})
        names = list(disciplines) if disciplines is not None else list(evaluator.specs)
        for n in names:
            if n not in evaluator.specs:
                raise ValueError(f"discipline {n!r} is not served by the evaluator; known: {sorted(evaluator.specs)}")
        self.specs = {n: evaluator.specs[n] for n in names}
        self.graph = CouplingGraph((s.name, s.inputs, s.outputs) for s in self.specs.values())
        self.n_evaluations = 0
        self.data_flow = bool(data_flow) and not self.graph.cycles
        self.n_newton_calls = 0  # evaluate() calls made by Newton steps (extra FD calls included)
        # loop disciplines a Newton step differences (no analytic partials); learnt from answers over ROS
        self._fd_only = {n for n, s in self.specs.items() if s.partials is False}
        self._flow_waves = [[c[0] for c in wave] for wave in self.graph.waves]

    # ------------------------------------------------------------------ helpers
    def _call_inputs(self, name: str, values: dict, rows: np.ndarray) -> dict[str, np.ndarray]:
        spec = self.specs[name]
        out = {v: values[v][rows] for v in spec.inputs}
        out.update({p: values[p][rows] for p in spec.parameters if p in values})
        return out

    def _run(self, names: Sequence[str], values: dict, rows: np.ndarray, ok: np.ndarray,
             errors: list[str], relax: bool = False, partials: dict | None = None, store: bool = True) -> None:
        """One evaluate() call for ``names`` on ``rows``; writes outputs, marks failures.
        With ``partials`` (a dict) the disciplines' analytic partials are asked for and kept there."""
        if rows.size == 0 or not names:
            return
        calls = [(n, self._call_inputs(n, values, rows)) for n in names]
        if partials is None:
            results = self.evaluator.evaluate(calls)
        else:
            results = self.evaluator.evaluate(calls, partials=True)
        n_all = len(ok)
        for name, res in zip(names, results):
            if store:
                self._store(name, res, values, rows, ok, errors, relax)
            if partials is not None and "partials" in res.extra:
                got = partials.setdefault(name, {})
                for k, col in res.extra["partials"].items():
                    got.setdefault(k, np.zeros(n_all))[rows] = col

    def _store_rows(self, name: str, res, local: np.ndarray, values: dict, rows: np.ndarray, ok: np.ndarray,
                    errors: list[str]) -> None:
        """Like _store for the entries ``local`` of a result."""
        sub = EvalResult({o: np.asarray(res.outputs[o], dtype=float)[local] for o in self.specs[name].outputs},
                         np.asarray(res.ok, dtype=bool)[local], "")
        before = ok[rows].copy()
        self._store(name, sub, values, rows, ok, errors)
        for q in np.flatnonzero(before & ~ok[rows]):
            errors[rows[q]] = res.message(int(local[q]), int(rows[q]), name)

    def _store(self, name: str, res, values: dict, rows: np.ndarray, ok: np.ndarray, errors: list[str],
               relax: bool = False, points: np.ndarray | None = None) -> None:
        """Write one discipline's result for ``rows`` into ``values``; mark its failed points
        (named by ``points``, the batch's indices of ``rows``, when those are local)."""
        good = np.asarray(res.ok, dtype=bool)
        for v in self.specs[name].outputs:
            new = np.asarray(res.outputs[v], dtype=float)
            if relax and self.relaxation != 1.0:
                old = values[v][rows]
                new = np.where(np.isfinite(old), old + self.relaxation * (new - old), new)
            values[v][rows] = new
        if not good.all():
            points = rows if points is None else points
            for local in np.flatnonzero(~good):
                i = rows[local]
                if ok[i]:
                    ok[i] = False
                    errors[i] = res.message(int(local), int(points[local]), name)

    # --------------------------------------------------------------------- run
    def run(self, inputs: Mapping[str, np.ndarray], partials: bool = False) -> MDAResult:
        """Analyse the batch given by ``inputs`` (design variables and parameter overrides).

        With ``partials`` the disciplines that have analytic partials return them at the
        analysed point: with their result in a feed-forward graph (no extra evaluation), and
        for a discipline inside a loop by one more call at the converged values (counted)."""
        cols = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in inputs.items()}
        n = max((c.size for c in cols.values()), default=0)
        values = {k: np.broadcast_to(c, (n,)).copy() for k, c in cols.items()}
        self.graph.check_inputs(values)
        for v in self.graph.producer:
            if v not in values:
                values[v] = np.full(n, np.nan)
        ok = np.ones(n, dtype=bool)
        errors = [""] * n
        iterations = np.zeros(n, dtype=int)
        self.n_evaluations += n
        part: dict | None = {} if partials else None
        if self.data_flow:
            self._flow(values, n, ok, errors, part)
        else:
            fused: set[str] = set()  # evaluated inside a Newton loop's waves (fuse_downstream)
            for w, wave in enumerate(self.graph.waves):
                singles = [c[0] for c in wave if not self.graph.is_cyclic(c) and c[0] not in fused]
                self._run(singles, values, np.flatnonzero(ok), ok, errors, partials=part)
                for comp in wave:
                    if self.graph.is_cyclic(comp):
                        if self.method == "newton":  # its last call's partials are at the converged values
                            tail = self._downstream(comp, w) if self.fuse_downstream else []
                            self._newton(comp, values, ok, errors, iterations, cols, part, tail)
                            fused.update(tail)
                            continue
                        self._loop(comp, values, ok, errors, iterations, cols)
                        capable = [m for m in comp if self.specs[m].partials is not False]
                        if part is not None and capable:
                            # partials at the converged values; the outputs stay the loop's
                            self._run(capable, values, np.flatnonzero(ok), ok, errors, partials=part, store=False)
        for v in self.graph.producer:
            values[v][~ok] = np.nan
        return MDAResult(values, ok, errors, iterations, part)

    def _flow(self, values: dict, n: int, ok: np.ndarray, errors: list[str], partials: dict | None = None) -> None:
        """Feed-forward graph: one data-flow evaluation (flow.py); errors in topological order."""
        if n == 0:
            return
        request = {k: v for k, v in values.items() if k not in self.graph.producer}
        results = evaluate_flow(self.evaluator, self.specs, self._flow_waves, request, n, partials is not None)
        everything = np.arange(n)
        for wave in self._flow_waves:
            for name in wave:
                self._store(name, results[name], values, everything, ok, errors)
                if partials is not None and "partials" in results[name].extra:
                    partials[name] = dict(results[name].extra["partials"])

    def _loop(self, comp: Sequence[str], values: dict, ok: np.ndarray, errors: list[str],
              iterations: np.ndarray, given: Mapping[str, np.ndarray]) -> None:
        outs = [v for m in comp for v in self.specs[m].outputs]
        loop_reads = {v for m in comp for v in self.specs[m].inputs}
        couplings = [v for v in outs if v in loop_reads]
        rows = np.flatnonzero(ok)
        warm = self._warm.get(tuple(comp)) if self.warm_start else None
        for v in (couplings if warm is not None else self.graph.torn_inputs(comp)):
            if v not in given:
                values[v][rows] = warm[v] if warm is not None else self.guesses.get(
                    v, self.guesses.get(base_name(v), 1.0))
        if self.method == "jacobi" and warm is None:  # seed every loop input by one sequential pass
            for m in comp:
                self._run([m], values, rows[ok[rows]], ok, errors)
        converged: list[int] = []
        try:
            self._sweeps(comp, values, ok, errors, iterations, outs, rows[ok[rows]], converged)
        finally:
            if converged and self.warm_start:  # deterministic: the batch's first converged point
                first = min(converged)
                self._warm[tuple(comp)] = {v: float(values[v][first]) for v in couplings}

    def _sweeps(self, comp, values, ok, errors, iterations, outs, active, converged) -> None:
        err = np.full(active.size, np.inf)
        for it in range(1, self.max_iterations + 1):
            if active.size == 0:
                return
            old = np.array([values[v][active] for v in outs])
            if self.method == "gauss_seidel":
                for m in comp:
                    self._run([m], values, active[ok[active]], ok, errors, relax=True)
            else:
                self._run(list(comp), values, active, ok, errors, relax=True)
            new = np.array([values[v][active] for v in outs])
            with np.errstate(invalid="ignore"):
                err = np.max(np.abs(new - old) / np.maximum(np.abs(new), 1.0), axis=0)
            err = np.where(np.isfinite(err), err, np.inf)
            iterations[active] = it
            alive = ok[active]
            done = alive & (err <= self.tolerance)
            converged.extend(active[done].tolist())
            active, err = active[alive & ~done], err[alive & ~done]
        for i, e in zip(active, err):
            ok[i] = False
            errors[i] = (f"MDA loop {list(comp)} did not converge in {self.max_iterations} "
                         f"{self.method} iterations (relative change {e:.3g} > tolerance {self.tolerance:g})")

    # ------------------------------------------------------------------ newton
    def _downstream(self, comp: Sequence[str], w: int) -> list[str]:
        """Feed-forward disciplines of later waves that can run in the request wave of every
        Newton step of ``comp`` (``fuse_downstream``): they read at least one of the loop's
        couplings (outputs a loop discipline reads, so their value in a step is that step's y),
        and all their other inputs are design inputs or outputs of disciplines of earlier waves
        or of the feed-forward disciplines of wave ``w`` (already evaluated then)."""
        g = self.graph
        in_loop = set(comp)
        loop_reads = {v for m in comp for v in self.specs[m].inputs}
        couplings = {v for m in comp for v in self.specs[m].outputs if v in loop_reads}
        ready: set[str] = set()
        for k, wave in enumerate(g.waves[:w + 1]):
            for c in wave:
                if k < w or not g.is_cyclic(c):
                    ready.update(c)
        tail = []
        for wave in g.waves[w + 1:]:
            for c in wave:
                if g.is_cyclic(c):
                    continue
                d = c[0]
                src = {v: g.producer.get(v) for v in self.specs[d].inputs}
                reads_loop = any(p in in_loop for p in src.values())
                fits = all(p is None or (p in ready and p not in in_loop) or (p in in_loop and v in couplings)
                           for v, p in src.items())
                if reads_loop and fits:
                    tail.append(d)
        return tail

    def _newton_calls(self, names: Sequence[str], values: dict, rows: np.ndarray, unknowns: Sequence[str]):
        """Calls for one Newton evaluation: a discipline in ``_fd_only`` gets its base points
        followed by one block per coupling input perturbed (forward differences)."""
        calls, plans = [], []
        for name in names:
            inputs = self._call_inputs(name, values, rows)
            if name in self._fd_only:
                pert = [v for v in self.specs[name].inputs if v in unknowns]
                h = {v: FD_STEP * np.maximum(np.abs(inputs[v]), 1.0) for v in pert}
                blocks = [inputs]
                for v in pert:
                    blocks.append({**inputs, v: inputs[v] + h[v]})
                inputs = {k: np.concatenate([b[k] for b in blocks]) for k in inputs}
                plans.append((pert, h))
            else:
                plans.append(None)
            calls.append((name, inputs))
        return calls, plans

    def _newton(self, comp: Sequence[str], values: dict, ok: np.ndarray, errors: list[str],
                iterations: np.ndarray, given: Mapping[str, np.ndarray], partials: dict | None,
                tail: Sequence[str] = ()) -> None:
        """Newton-Raphson over the loop ``comp`` (module docstring); per-point status like _loop.
        ``tail``: downstream disciplines evaluated in every step's call (``_downstream``); a point
        keeps their results of the step at which it converged."""
        spec_in = {m: set(self.specs[m].inputs) for m in comp}
        outs = [v for m in comp for v in self.specs[m].outputs]
        unknowns = [v for v in outs if any(v in spec_in[m] for m in comp)]
        col = {v: k for k, v in enumerate(unknowns)}
        rows = np.flatnonzero(ok)
        torn = self.graph.torn_inputs(comp)
        warm = self._warm.get(tuple(comp)) if self.warm_start else None
        if warm is not None:  # every coupling from the last MDA's converged values: no seeding call
            start = self._predict(tuple(comp), values, rows)
            for v in unknowns:
                if v not in given:
                    values[v][rows] = warm[v] if start is None else start[v]
        else:
            for v in torn:
                if v not in given:
                    values[v][rows] = self.guesses.get(v, self.guesses.get(base_name(v), 1.0))
            for m in comp:  # seed the forward couplings (one sequential call per producing discipline)
                if any(v in col and v not in torn and v not in given for v in self.specs[m].outputs):
                    self._run([m], values, rows[ok[rows]], ok, errors)
        active = rows[ok[rows]]
        err = np.full(active.size, np.inf)
        converged: list[int] = []
        tangent: dict = {}
        try:
            self._newton_steps(comp, values, ok, errors, iterations, partials, tail, outs, unknowns, col,
                               active, err, converged, tangent)
        finally:
            if converged and self.warm_start:  # deterministic: the batch's first converged point
                first = min(converged)
                self._warm[tuple(comp)] = {v: float(values[v][first]) for v in unknowns}
                self._tangent[tuple(comp)] = tangent.get(first)

    def _predict(self, key: tuple, values: dict, rows: np.ndarray) -> dict | None:
        """First-order prediction of the couplings at ``rows`` from the stored converged point:
        y_ref + dy/dx (x - x_ref), dy/dx = (I - J)^-1 dF/dx at the reference (None: not available)."""
        t = self._tangent.get(key) if self.tangent else None
        if t is None:
            return None
        unknowns, xs, x_ref, S, y_ref = t
        dx = np.array([values[x][rows] - x_ref[k] for k, x in enumerate(xs)])  # (nx, n)
        Y = y_ref[:, None] + S @ dx if xs else np.repeat(y_ref[:, None], rows.size, axis=1)
        if not np.isfinite(Y).all():
            return None
        return {v: Y[k] for k, v in enumerate(unknowns)}

    def _keep_tangent(self, comp, values, results, J, active, done, converged, col, unknowns, tangent) -> None:
        """The tangent dy/dx at the lowest converged row so far (if it converged in this step)."""
        first = min(converged)
        where = np.flatnonzero(active == first)
        if not where.size or not done[where[0]]:
            return
        q = where[0]
        xs = sorted({i for m in comp for i in self.specs[m].inputs if i not in col}
                    | {p for m in comp for p in self.specs[m].parameters if p in values})
        xi = {x: k for k, x in enumerate(xs)}
        dF = np.zeros((len(unknowns), len(xs)))
        for res in results:
            for (o, i), c in res.extra.get("partials", {}).items():
                if o in col and i in xi:
                    dF[col[o], xi[i]] = np.asarray(c)[q]
        try:
            S = np.linalg.solve(np.eye(len(unknowns)) - J[q], dF)
        except np.linalg.LinAlgError:
            return
        tangent.clear()
        tangent[first] = (list(unknowns), xs, np.array([values[x][first] for x in xs]), S,
                          np.array([values[v][first] for v in unknowns]))

    def _newton_steps(self, comp, values, ok, errors, iterations, partials, tail, outs, unknowns, col,
                      active, err, converged, tangent) -> None:
        u = len(unknowns)
        for it in range(1, self.max_iterations + 1):
            if active.size == 0:
                return
            n = active.size
            calls, plans = self._newton_calls(comp, values, active, unknowns)
            calls += [(d, self._call_inputs(d, values, active)) for d in tail]
            results = list(self.evaluator.evaluate(calls, partials=True))
            tail_results = results[len(comp):]
            results = results[:len(comp)]
            self.n_newton_calls += 1
            late = [m for m, p, r in zip(comp, plans, results) if p is None and "partials" not in r.extra
                    and np.asarray(r.ok, dtype=bool).any()]
            if late:  # no analytic partials (learnt now): difference these from here on, this step too
                self._fd_only.update(late)
                extra_calls, extra_plans = self._newton_calls(late, values, active, unknowns)
                extra = self.evaluator.evaluate(extra_calls)
                self.n_newton_calls += 1
                for m, p, r in zip(late, extra_plans, extra):
                    k = comp.index(m)
                    results[k], plans[k] = r, p
            F = {v: values[v][active].copy() for v in outs}
            J = np.zeros((n, u, u))
            J_ok = np.ones(n, dtype=bool)
            for m, plan, res in zip(comp, plans, results):
                m_outs = self.specs[m].outputs
                nb = 1 if plan is None else 1 + len(plan[0])
                Y = {o: np.asarray(res.outputs[o], dtype=float).reshape(nb, n) for o in m_outs}
                OK = np.asarray(res.ok, dtype=bool).reshape(nb, n)
                base = EvalResult({o: Y[o][0] for o in m_outs}, OK[0], res.error,
                                  point_errors={j: e for j, e in res.point_errors.items() if j < n})
                ok_local, errs = np.ones(n, dtype=bool), [""] * n
                self._store(m, base, F, np.arange(n), ok_local, errs, points=active)
                for j in np.flatnonzero(~ok_local):
                    if ok[active[j]]:
                        ok[active[j]] = False
                        errors[active[j]] = errs[j]
                if plan is None:
                    got = res.extra.get("partials", {})
                    for (o, i), c in got.items():
                        if o in col and i in col:
                            J[:, col[o], col[i]] = c
                    if partials is not None and "partials" in res.extra:
                        keep = partials.setdefault(m, {})
                        for key, c in got.items():
                            keep.setdefault(key, np.zeros(len(ok)))[active] = c
                else:
                    pert, h = plan
                    for b, v in enumerate(pert, start=1):
                        J_ok &= OK[b]
                        for o in m_outs:
                            if o in col:
                                J[:, col[o], col[v]] = (Y[o][b] - Y[o][0]) / h[v]
            for v in outs:
                if v not in col:  # read by no loop discipline: its value at y is final
                    values[v][active] = F[v]
            y = np.array([values[v][active] for v in unknowns])  # (u, n)
            fy = np.array([F[v] for v in unknowns])
            with np.errstate(invalid="ignore"):
                err = np.max(np.abs(fy - y) / np.maximum(np.abs(fy), 1.0), axis=0) if u else np.zeros(n)
            err = np.where(np.isfinite(err), err, np.inf)
            iterations[active] = it
            alive = ok[active]
            done = alive & (err <= self.tolerance)
            converged.extend(active[done].tolist())
            if self.tangent and done.any() and all(p is None for p in plans):
                self._keep_tangent(comp, values, results, J, active, done, converged, col, unknowns, tangent)
            if tail and done.any():  # the tail saw this step's y, which is the loop's result there
                local = np.flatnonzero(done)
                for d, res in zip(tail, tail_results):
                    self._store_rows(d, res, local, values, active[local], ok, errors)
                    if partials is not None and "partials" in res.extra:
                        keep = partials.setdefault(d, {})
                        for key, c in res.extra["partials"].items():
                            keep.setdefault(key, np.zeros(len(ok)))[active[local]] = np.asarray(c)[local]
            step = alive & ~done
            bad_fd = step & ~J_ok
            for j in np.flatnonzero(bad_fd):
                ok[active[j]] = False
                errors[active[j]] = (f"MDA loop {list(comp)}: a finite-difference Jacobian point failed "
                                     f"in newton iteration {it}")
            step &= J_ok
            if step.any():
                A = np.eye(u)[None] - J[step]
                r = (fy - y)[:, step].T  # (k, u)
                dy = np.full(r.shape, np.nan)
                try:
                    dy = np.linalg.solve(A, r[..., None])[..., 0]
                except np.linalg.LinAlgError:  # some point singular: solve them one by one
                    for q in range(len(A)):
                        try:
                            dy[q] = np.linalg.solve(A[q], r[q])
                        except np.linalg.LinAlgError:
                            pass
                idx = np.flatnonzero(step)
                good = np.isfinite(dy).all(axis=1)
                for q in np.flatnonzero(~good):
                    i = active[idx[q]]
                    ok[i] = False
                    errors[i] = (f"MDA loop {list(comp)}: singular Newton system I - dF/dy "
                                 f"in newton iteration {it}")
                for k, v in enumerate(unknowns):
                    values[v][active[idx[good]]] += self.relaxation * dy[good, k]
            keep = ok[active] & ~done
            active, err = active[keep], err[keep]
        for i, e in zip(active, err):
            ok[i] = False
            errors[i] = (f"MDA loop {list(comp)} did not converge in {self.max_iterations} "
                         f"newton iterations (relative change {e:.3g} > tolerance {self.tolerance:g})")
