"""Multidisciplinary analysis (MDA) of a batch of N design points.

An acyclic (feed-forward) graph is analysed by data flow (``flow.py``): one request for the whole
MDA when the evaluator offers it (the ROS nodes pass results from node to node), else one
``evaluator.evaluate`` call per wave; a discipline evaluates the points its sources evaluated.
A graph with loops runs wave by wave: one call per wave holds every feed-forward discipline of
that wave, and each feedback loop is iterated by the loop solver named by ``method``
(``SOLVERS``: gauss_seidel.py, jacobi.py, newton.py), vectorised over the points still iterating.
A point whose discipline fails, or whose loop does not converge, gets ``ok`` False, an ``MDAError``
and NaN for every output that depends on the failure (what does not, e.g. a motor speed beside a
failed energy, is kept); nothing raises.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np

from bev_mdo.mdo.evaluator import Evaluator
from bev_mdo.mdo.flow import evaluate_flow
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.mda.base import Batch, Calls, LoopSolver, MDAResult
from bev_mdo.mdo.mda.gauss_seidel import GaussSeidel
from bev_mdo.mdo.mda.jacobi import Jacobi
from bev_mdo.mdo.mda.newton import Newton

# The loop solvers by the name ``mda.method`` gives (OpenMDAO's solvers swapped by name).
SOLVERS: dict[str, type[LoopSolver]] = {cls.name: cls for cls in (GaussSeidel, Jacobi, Newton)}
METHODS = tuple(SOLVERS)


class MDA:
    """Batched multidisciplinary analysis over an evaluator.

    ``guesses`` are starting values for loop (coupling) variables, default 1.0; an input column
    with the variable's name overrides the guess per point. The loop settings (``tolerance``,
    ``max_iterations``, ``relaxation``, ``warm_start``, ``fuse_downstream``) go to the solver.
    ``n_evaluations`` counts analysed points. ``data_flow`` False analyses an acyclic graph wave by
    wave with the loop rule instead (a wave runs the points still good)."""

    def __init__(self, evaluator: Evaluator, *, method: str = "gauss_seidel",
                 guesses: Mapping[str, float] | None = None, disciplines: Sequence[str] | None = None,
                 data_flow: bool = True, **settings):
        if method not in SOLVERS:
            raise ValueError(f"mda method {method!r} is unknown; allowed: {', '.join(SOLVERS)}")
        names = list(disciplines) if disciplines is not None else list(evaluator.specs)
        for n in names:
            if n not in evaluator.specs:
                raise ValueError(f"discipline {n!r} is not served by the evaluator; known: {sorted(evaluator.specs)}")
        self.evaluator, self.method = evaluator, method
        self.specs = {n: evaluator.specs[n] for n in names}
        self.graph = CouplingGraph((s.name, s.inputs, s.outputs) for s in self.specs.values())
        self.calls = Calls(evaluator, self.specs)
        self.solver = SOLVERS[method](self.calls, self.graph, guesses=guesses, **settings)
        self.n_evaluations = 0
        self.data_flow = bool(data_flow) and not self.graph.cycles
        self._flow_waves = [[c[0] for c in wave] for wave in self.graph.waves]

    @property
    def warm_start(self) -> bool:
        return self.solver.warm_start

    @property
    def fuse_downstream(self) -> bool:
        return self.solver.fuse_downstream

    def run(self, inputs: Mapping[str, np.ndarray], partials: bool = False) -> MDAResult:
        """Analyse the batch given by ``inputs`` (design variables and parameter overrides).

        With ``partials`` the disciplines that have analytic partials return them at the analysed
        point: with their result in a feed-forward graph (no extra evaluation), and for a
        discipline inside a loop from the solver's last call or one more call at the converged
        values (counted)."""
        cols = {k: np.atleast_1d(np.asarray(v, dtype=float)) for k, v in inputs.items()}
        n = max((c.size for c in cols.values()), default=0)
        values = {k: np.broadcast_to(c, (n,)).copy() for k, c in cols.items()}
        self.graph.check_inputs(values)
        for v in self.graph.producer:
            if v not in values:
                values[v] = np.full(n, np.nan)
        b = Batch(values, np.ones(n, dtype=bool), [None] * n, np.zeros(n, dtype=int), cols,
                  {} if partials else None)
        self.n_evaluations += n
        if self.data_flow:
            self._flow(b, n)
        else:
            fused: set[str] = set()  # evaluated inside a loop solver's calls (fuse_downstream)
            for w, wave in enumerate(self.graph.waves):
                singles = [c[0] for c in wave if not self.graph.is_cyclic(c) and c[0] not in fused]
                self.calls.run(singles, b, np.flatnonzero(b.ok), partials=b.partials)
                for comp in wave:
                    if self.graph.is_cyclic(comp):
                        fused.update(self.solver.solve(comp, b, w))
        self._unsound_to_nan(b)
        return MDAResult(values, b.ok, b.errors, b.iterations, b.partials)

    def _unsound_to_nan(self, b: Batch) -> None:
        """A failed point keeps the outputs that do not depend on what failed: those of a discipline
        outside any loop that evaluated the point from sound inputs (a 21 t design kept its motor speed
        and cost); every other output there is NaN (a loop's unconverged iterates among them)."""
        bad = np.flatnonzero(~b.ok)
        if bad.size == 0:
            return
        sound: dict[str, np.ndarray] = {}  # produced variable -> sound at the failed points
        for wave in self.graph.waves:
            for comp in wave:
                for name in comp:
                    ok = np.zeros(bad.size, dtype=bool)
                    if not self.graph.is_cyclic(comp) and name in b.evaluated:
                        ok = b.evaluated[name][bad].copy()
                        for v in self.specs[name].inputs:
                            if v in sound:  # produced upstream (an earlier wave)
                                ok &= sound[v]
                    for v in self.specs[name].outputs:
                        sound[v] = ok
                        b.values[v][bad[~ok]] = np.nan

    def _flow(self, b: Batch, n: int) -> None:
        """Feed-forward graph: one data-flow evaluation (flow.py); errors in topological order."""
        if n == 0:
            return
        request = {k: v for k, v in b.values.items() if k not in self.graph.producer}
        results = evaluate_flow(self.evaluator, self.specs, self._flow_waves, request, n, b.partials is not None)
        everything = np.arange(n)
        for wave in self._flow_waves:
            for name in wave:
                self.calls.store(name, results[name], b, everything)
                if b.partials is not None and "partials" in results[name].extra:
                    b.partials[name] = dict(results[name].extra["partials"])
