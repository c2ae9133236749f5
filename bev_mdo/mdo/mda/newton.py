"""Newton-Raphson over a loop's couplings (``method: newton``; OpenMDAO's NewtonSolver, GEMSEO's
MDANewtonRaphson).

It solves R(y) = F(y) - y = 0 over the loop's couplings y: each step evaluates ALL loop disciplines
at y in ONE ``evaluate`` call with their partials (a discipline without analytic partials: forward
finite differences, step ``FD_STEP`` max(|y|, 1), its perturbed points in the same call), solves
(I - J) dy = F(y) - y batched over the points, then y <- y + relaxation * dy. Seeding, convergence,
failures, warm start (``tangent``) and ``fuse_downstream``: docs/derivatives.md, "Newton MDA".
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bev_mdo.mdo.discipline import EvalResult
from bev_mdo.mdo.mda.base import Batch, LoopSolver, keep_partials, loop_couplings
from bev_mdo.mdo.mda.tangent import keep_tangent, predict

FD_STEP = 1e-7  # relative forward-difference step of a Jacobian column without analytic partials


class Newton(LoopSolver):
    name = "newton"
    auto_warm_start = True  # its converged couplings are exact far below the tolerance

    def __init__(self, calls, graph, *, warm_start="auto", fuse_downstream=False, **settings):
        super().__init__(calls, graph, warm_start=warm_start, fuse_downstream=fuse_downstream, **settings)
        self.tangent = warm_start == "tangent"
        self.fuse_downstream = bool(fuse_downstream)
        self.tangents: dict[tuple, tuple | None] = {}  # loop -> its tangent dy/dx at the warm point
        self.n_calls = 0  # evaluate() calls made by Newton steps (extra FD calls included)
        # loop disciplines a step differences (no analytic partials); learnt from answers over ROS
        self.fd_only = {n for n, s in self.specs.items() if s.partials is False}

    def downstream(self, comp: Sequence[str], w: int) -> list[str]:
        """Feed-forward disciplines of later waves that can run in the request wave of every step
        of ``comp`` (``fuse_downstream``): they read at least one of the loop's couplings (outputs a
        loop discipline reads, so their value in a step is that step's y), and all their other
        inputs are design inputs or outputs of disciplines of earlier waves or of the feed-forward
        disciplines of wave ``w`` (already evaluated then)."""
        g = self.graph
        in_loop = set(comp)
        couplings = set(loop_couplings(self.specs, comp)[1])
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

    def _step_calls(self, names: Sequence[str], values: dict, rows: np.ndarray, unknowns: Sequence[str]):
        """Calls for one evaluation: a discipline in ``fd_only`` gets its base points followed by one
        block per coupling input perturbed (forward differences)."""
        calls, plans = [], []
        for name in names:
            inputs = self.calls.inputs(name, values, rows)
            if name in self.fd_only:
                pert = [v for v in self.specs[name].inputs if v in unknowns]
                h = {v: FD_STEP * np.maximum(np.abs(inputs[v]), 1.0) for v in pert}
                blocks = [inputs] + [{**inputs, v: inputs[v] + h[v]} for v in pert]
                inputs = {k: np.concatenate([blk[k] for blk in blocks]) for k in inputs}
                plans.append((pert, h))
            else:
                plans.append(None)
            calls.append((name, inputs))
        return calls, plans

    def solve(self, comp: Sequence[str], b: Batch, w: int) -> list[str]:
        """Newton-Raphson over the loop ``comp`` (module docstring); return the fused tail."""
        tail = self.downstream(comp, w) if self.fuse_downstream else []
        outs, unknowns = loop_couplings(self.specs, comp)
        rows = np.flatnonzero(b.ok)
        torn = self.graph.torn_inputs(comp)
        warm = self.warm.get(tuple(comp)) if self.warm_start else None
        if warm is not None:  # every coupling from the last MDA's converged values: no seeding call
            start = predict(self.tangents.get(tuple(comp)) if self.tangent else None, b.values, rows)
            for v in unknowns:
                if v not in b.given:
                    b.values[v][rows] = warm[v] if start is None else start[v]
        else:
            for v in torn:
                if v not in b.given:
                    b.values[v][rows] = self.guess(v)
            for m in comp:  # seed the forward couplings (one sequential call per producing discipline)
                if any(v in unknowns and v not in torn and v not in b.given for v in self.specs[m].outputs):
                    self.calls.run([m], b, rows[b.ok[rows]])
        converged: list[int] = []
        tangent: dict = {}
        try:
            self._steps(comp, b, tail, outs, unknowns, rows[b.ok[rows]], converged, tangent)
        finally:
            first = self.keep_warm(comp, b, unknowns, converged)
            if first is not None:
                self.tangents[tuple(comp)] = tangent.get(first)
        return tail

    def _evaluate(self, comp, tail, b: Batch, active, unknowns):
        """One step's call (and the extra FD call for disciplines learnt to lack partials)."""
        calls, plans = self._step_calls(comp, b.values, active, unknowns)
        calls += [(d, self.calls.inputs(d, b.values, active)) for d in tail]
        results = list(self.calls.evaluator.evaluate(calls, partials=True))
        tail_results = results[len(comp):]
        results = results[:len(comp)]
        self.n_calls += 1
        late = [m for m, p, r in zip(comp, plans, results) if p is None and "partials" not in r.extra
                and np.asarray(r.ok, dtype=bool).any()]
        if late:  # no analytic partials (learnt now): difference these from here on, this step too
            self.fd_only.update(late)
            extra_calls, extra_plans = self._step_calls(late, b.values, active, unknowns)
            extra = self.calls.evaluator.evaluate(extra_calls)
            self.n_calls += 1
            for m, p, r in zip(late, extra_plans, extra):
                k = comp.index(m)
                results[k], plans[k] = r, p
        return results, plans, tail_results

    def _assemble(self, comp, b: Batch, active, results, plans, outs, col):
        """F(y) of every loop output, J = dF/dy per point, and which points' FD columns are good."""
        n, u = active.size, len(col)
        F = {v: b.values[v][active].copy() for v in outs}
        J = np.zeros((n, u, u))
        J_ok = np.ones(n, dtype=bool)
        for m, plan, res in zip(comp, plans, results):
            m_outs = self.specs[m].outputs
            nb = 1 if plan is None else 1 + len(plan[0])
            Y = {o: np.asarray(res.outputs[o], dtype=float).reshape(nb, n) for o in m_outs}
            OK = np.asarray(res.ok, dtype=bool).reshape(nb, n)
            base = EvalResult({o: Y[o][0] for o in m_outs}, OK[0], res.error,
                              point_errors={j: e for j, e in res.point_errors.items() if j < n})
            local = Batch(F, np.ones(n, dtype=bool), [None] * n, np.zeros(n, dtype=int), {})
            self.calls.store(m, base, local, np.arange(n), points=active)
            for j in np.flatnonzero(~local.ok):
                e = local.errors[j]
                b.fail(active[j], e.kind, e.message, e.discipline)
            if plan is None:
                got = res.extra.get("partials", {})
                for (o, i), c in got.items():
                    if o in col and i in col:
                        J[:, col[o], col[i]] = c
                if b.partials is not None and "partials" in res.extra:
                    keep_partials(b.partials, m, got, active, len(b.ok))
            else:
                pert, h = plan
                for k, v in enumerate(pert, start=1):
                    J_ok &= OK[k]
                    for o in m_outs:
                        if o in col:
                            J[:, col[o], col[v]] = (Y[o][k] - Y[o][0]) / h[v]
        return F, J, J_ok

    def _steps(self, comp, b: Batch, tail, outs, unknowns, active, converged, tangent) -> None:
        col = {v: k for k, v in enumerate(unknowns)}
        err = np.full(active.size, np.inf)
        for it in range(1, self.max_iterations + 1):
            if active.size == 0:
                return
            results, plans, tail_results = self._evaluate(comp, tail, b, active, unknowns)
            F, J, J_ok = self._assemble(comp, b, active, results, plans, outs, col)
            for v in outs:
                if v not in col:  # read by no loop discipline: its value at y is final
                    b.values[v][active] = F[v]
            y = np.array([b.values[v][active] for v in unknowns])  # (u, n)
            fy = np.array([F[v] for v in unknowns])
            err, alive, done = self.check(b, active, fy, y, it, converged)
            if self.tangent and done.any() and all(p is None for p in plans):
                keep_tangent(self.specs, comp, b.values, results, J, active, done, converged, col, unknowns,
                             tangent)
            if tail and done.any():  # the tail saw this step's y, which is the loop's result there
                local = np.flatnonzero(done)
                for d, res in zip(tail, tail_results):
                    self.calls.store(d, res, b, active[local], local=local)
                    if b.partials is not None and "partials" in res.extra:
                        keep_partials(b.partials, d, res.extra["partials"], active[local], len(b.ok), local)
            step = alive & ~done
            for j in np.flatnonzero(step & ~J_ok):
                b.fail(active[j], "fd_failed", f"MDA loop {list(comp)}: a finite-difference Jacobian point "
                       f"failed in newton iteration {it}", loop=comp)
            step &= J_ok
            if step.any():
                self._update(comp, b, active, step, J, fy - y, unknowns, it)
            keep = b.ok[active] & ~done
            active, err = active[keep], err[keep]
        self.not_converged(comp, b, active, err)

    def _update(self, comp, b: Batch, active, step, J, residual, unknowns, it) -> None:
        """y <- y + relaxation dy, (I - J) dy = F(y) - y, for the points that take a step."""
        A = np.eye(len(unknowns))[None] - J[step]
        r = residual[:, step].T  # (k, u)
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
            b.fail(active[idx[q]], "singular", f"MDA loop {list(comp)}: singular Newton system I - dF/dy "
                   f"in newton iteration {it}", loop=comp)
        for k, v in enumerate(unknowns):
            b.values[v][active[idx[good]]] += self.relaxation * dy[good, k]
