"""The fixed-point loop solvers' shared iteration: start, sweep until the relative change of every
loop output is within the tolerance, per point, over the points still iterating.

A subclass says what one sweep is (``sweep``) and how a cold start is seeded (``seed``).
Convergence: max over the loop outputs of |new - old| / max(|new|, 1) <= tolerance, the changes shrinking
(LoopSolver.check).
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bev_mdo.mdo.mda.base import Batch, LoopSolver, loop_couplings


class FixedPoint(LoopSolver):
    """Gauss-Seidel and Jacobi: iterate y <- F(y) (relaxed: y + relaxation (F(y) - y))."""

    def seed(self, comp: Sequence[str], b: Batch, rows: np.ndarray) -> None:
        """A cold start after the torn couplings got their guesses (nothing more by default)."""

    def sweep(self, comp: Sequence[str], b: Batch, active: np.ndarray) -> None:  # pragma: no cover
        raise NotImplementedError

    def solve(self, comp: Sequence[str], b: Batch, w: int) -> list[str]:
        outs, couplings = loop_couplings(self.specs, comp)
        rows = np.flatnonzero(b.ok)
        warm = self.warm.get(tuple(comp)) if self.warm_start else None
        for v in (couplings if warm is not None else self.graph.torn_inputs(comp)):
            if v not in b.given:
                b.values[v][rows] = warm[v] if warm is not None else self.guess(v)
        if warm is None:
            self.seed(comp, b, rows)
        converged: list[int] = []
        try:
            self._sweeps(comp, b, outs, rows[b.ok[rows]], converged)
        finally:
            self.keep_warm(comp, b, couplings, converged)
        capable = [m for m in comp if self.specs[m].partials is not False]
        if b.partials is not None and capable:
            # partials at the converged values; the outputs stay the loop's
            self.calls.run(capable, b, np.flatnonzero(b.ok), partials=b.partials, store=False)
        return []

    def _sweeps(self, comp, b: Batch, outs, active, converged) -> None:
        err = np.full(active.size, np.inf)
        for it in range(1, self.max_iterations + 1):
            if active.size == 0:
                return
            old = np.array([b.values[v][active] for v in outs])
            self.sweep(comp, b, active)
            new = np.array([b.values[v][active] for v in outs])
            err, alive, done = self.check(b, active, new, old, it, converged)
            active, err = active[alive & ~done], err[alive & ~done]
        self.not_converged(comp, b, active, err)
