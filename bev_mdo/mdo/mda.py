"""Multidisciplinary analysis (MDA) of a batch of N design points.

An acyclic (feed-forward) graph is analysed by data flow (``flow.py``): one request for the
whole MDA when the evaluator offers it (the ROS nodes pass results from node to node), else
one ``evaluator.evaluate`` call per wave; a discipline evaluates the points its sources
evaluated. A graph with loops runs wave by wave: one call per wave holds every feed-forward
discipline of that wave. A feedback loop is
iterated by Gauss-Seidel (one call per discipline, in the loop's declared order)
or Jacobi (one call per sweep, all loop disciplines together, after one sequential
seeding pass from the torn-variable guesses), vectorised over
the points still iterating. A point whose discipline fails, or whose loop does
not converge, gets NaN outputs, ``ok`` False and an error text; nothing raises.
"""
from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from bev_mdo.mdo.evaluator import Evaluator
from bev_mdo.mdo.flow import evaluate_flow
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.vectors import base_name

METHODS = ("gauss_seidel", "jacobi")
_POINT = re.compile(r"at point (\d+)")


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
                 data_flow: bool = True):
        if method not in METHODS:
            raise ValueError(f"mda method {method!r} is unknown; allowed: {', '.join(METHODS)}")
        if not tolerance > 0:
            raise ValueError(f"mda tolerance {tolerance} must be > 0")
        if int(max_iterations) < 1:
            raise ValueError(f"mda max_iterations {max_iterations} must be >= 1")
        if not 0 < relaxation <= 2:
            raise ValueError(f"mda relaxation {relaxation} must be in (0, 2]")
        self.evaluator = evaluator
        self.method, self.tolerance = method, float(tolerance)
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

    def _store(self, name: str, res, values: dict, rows: np.ndarray, ok: np.ndarray, errors: list[str],
               relax: bool = False) -> None:
        """Write one discipline's result for ``rows`` into ``values``; mark its failed points."""
        good = np.asarray(res.ok, dtype=bool)
        for v in self.specs[name].outputs:
            new = np.asarray(res.outputs[v], dtype=float)
            if relax and self.relaxation != 1.0:
                old = values[v][rows]
                new = np.where(np.isfinite(old), old + self.relaxation * (new - old), new)
            values[v][rows] = new
        if not good.all():
            msgs = _split_errors(res.error)
            for local in np.flatnonzero(~good):
                i = rows[local]
                if ok[i]:
                    ok[i] = False
                    errors[i] = msgs.get(int(local), res.error or f"{name}: failed")

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
            for wave in self.graph.waves:
                singles = [c[0] for c in wave if not self.graph.is_cyclic(c)]
                self._run(singles, values, np.flatnonzero(ok), ok, errors, partials=part)
                for comp in wave:
                    if self.graph.is_cyclic(comp):
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
        rows = np.flatnonzero(ok)
        for v in self.graph.torn_inputs(comp):
            if v not in given:
                values[v][rows] = self.guesses.get(v, self.guesses.get(base_name(v), 1.0))
        if self.method == "jacobi":  # seed every loop input by one sequential pass from the torn guesses
            for m in comp:
                self._run([m], values, rows[ok[rows]], ok, errors)
        active = rows[ok[rows]]
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
            active, err = active[alive & ~done], err[alive & ~done]
        for i, e in zip(active, err):
            ok[i] = False
            errors[i] = (f"MDA loop {list(comp)} did not converge in {self.max_iterations} "
                         f"{self.method} iterations (relative change {e:.3g} > tolerance {self.tolerance:g})")


def _split_errors(text: str) -> dict[int, str]:
    """Map 'at point i' messages of an EvalResult error text to local row indices."""
    out: dict[int, str] = {}
    for part in text.split("; "):
        m = _POINT.search(part)
        if m:
            out.setdefault(int(m.group(1)), part)
    return out
