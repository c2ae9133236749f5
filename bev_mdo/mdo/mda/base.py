"""What every MDA solver shares: the result, its structured errors, the batch in progress, the
calls to the evaluator, and the loop-solver interface.

A loop solver (``LoopSolver``) iterates one feedback loop (a strongly connected component of the
coupling graph) over the points still good, in place on a ``Batch``: it writes the loop's outputs,
marks the points that failed and why, and counts each point's iterations. Nothing raises for a
failed point; a failed point ends with an ``MDAError`` and NaN for the outputs that depend on the failure.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from bev_mdo.mdo.discipline import EvalResult
from bev_mdo.mdo.evaluator import Evaluator
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.vectors import base_name

# What went wrong at a point: a discipline failed there (raised, non-finite output, no answer),
# a loop did not converge, Newton's system I - dF/dy was singular, or a finite-difference point
# of a Newton Jacobian failed.
KINDS = ("discipline", "not_converged", "singular", "fd_failed")


@dataclass(frozen=True)
class MDAError:
    """Why one point of an MDA failed.

    ``discipline``: the discipline that failed (kind ``discipline``), else '' and ``loop`` names
    the loop's disciplines; ``point``: the index in the batch; ``message``: the text for people;
    ``reason``: the discipline's own words, without the point and its inputs (one design's report)."""

    discipline: str
    point: int
    kind: str
    message: str
    loop: tuple[str, ...] = ()
    reason: str = ""

    def __str__(self) -> str:
        return self.message


@dataclass
class MDAResult:
    """All variables of the batch (inputs and outputs, shape (N,)) and per-point status."""

    values: dict[str, np.ndarray]
    ok: np.ndarray                    # bool (N,)
    errors: list[MDAError | None]     # None for a good point
    iterations: np.ndarray            # loop sweeps per point (0 for a feed-forward graph)
    partials: dict[str, dict] | None = None  # run(partials=True): discipline -> {(out, in): (N,)}
                                             # for every discipline that has analytic partials

    @property
    def messages(self) -> list[str]:
        """The errors as text, '' for a good point (CSV columns, reports)."""
        return [e.message if e is not None else "" for e in self.errors]


@dataclass
class Batch:
    """One MDA's batch in progress: every variable's column, per-point status, and the columns
    the caller gave (a given coupling column overrides the guess and the warm start)."""

    values: dict[str, np.ndarray]
    ok: np.ndarray
    errors: list[MDAError | None]
    iterations: np.ndarray
    given: Mapping[str, np.ndarray]
    partials: dict | None = None  # discipline -> {(out, in): (N,)} when partials are asked for
    # discipline -> the points its last evaluation succeeded at (a failed point keeps those outputs
    # that such evaluations made from sound inputs: MDA.run)
    evaluated: dict[str, np.ndarray] = field(default_factory=dict)
    changes: np.ndarray | None = None  # (2 L, N): per point, a loop's last changes, oldest first (LoopSolver.check)

    def fail(self, i: int, kind: str, message: str, discipline: str = "", loop: Sequence[str] = (),
             reason: str = "") -> None:
        """Mark point ``i`` failed, unless it failed already (the first reason stays)."""
        if self.ok[i]:
            self.ok[i] = False
            self.errors[i] = MDAError(discipline, int(i), kind, message, tuple(loop), reason)


class Calls:
    """The evaluator calls of an MDA and how their results are written into a ``Batch``."""

    def __init__(self, evaluator: Evaluator, specs: Mapping):
        self.evaluator = evaluator
        self.specs = specs

    def inputs(self, name: str, values: dict, rows: np.ndarray | slice) -> dict[str, np.ndarray]:
        """The columns of ``values`` discipline ``name`` reads (inputs, and parameters given), at ``rows``."""
        spec = self.specs[name]
        out = {v: values[v][rows] for v in spec.inputs}
        out.update({p: values[p][rows] for p in spec.parameters if p in values})
        return out

    def run(self, names: Sequence[str], b: Batch, rows: np.ndarray, relaxation: float = 1.0,
            partials: dict | None = None, store: bool = True) -> None:
        """One evaluate() call for ``names`` on ``rows``; writes outputs, marks failures.
        With ``partials`` (a dict) the disciplines' analytic partials are asked for and kept there."""
        if rows.size == 0 or not names:
            return
        calls = [(n, self.inputs(n, b.values, rows)) for n in names]
        if partials is None:
            results = self.evaluator.evaluate(calls)
        else:
            results = self.evaluator.evaluate(calls, partials=True)
        for name, res in zip(names, results):
            if store:
                self.store(name, res, b, rows, relaxation)
            if partials is not None and "partials" in res.extra:
                keep_partials(partials, name, res.extra["partials"], rows, len(b.ok))

    def store(self, name: str, res: EvalResult, b: Batch, rows: np.ndarray, relaxation: float = 1.0,
              points: np.ndarray | None = None, local: np.ndarray | None = None) -> None:
        """Write one discipline's result (its entries ``local``, default all) for ``rows`` into
        ``b``; mark its failed points (named by ``points``, the batch's indices of ``rows``, when
        ``b`` is local to a solver step)."""
        sel = slice(None) if local is None else local
        good = np.asarray(res.ok, dtype=bool)[sel]
        for v in self.specs[name].outputs:
            new = np.asarray(res.outputs[v], dtype=float)[sel]
            if relaxation != 1.0:
                old = b.values[v][rows]
                new = np.where(np.isfinite(old), old + relaxation * (new - old), new)
            b.values[v][rows] = new
        b.evaluated.setdefault(name, np.zeros(len(b.ok), dtype=bool))[rows] = good
        if not good.all():
            points = rows if points is None else points
            for j in np.flatnonzero(~good):
                entry = j if local is None else local[j]
                why = res.point_errors.get(int(entry))
                b.fail(rows[j], "discipline", res.message(int(entry), int(points[j]), name), name,
                       reason=why.reason if why is not None else "")


def keep_partials(partials: dict, name: str, got: Mapping, rows: np.ndarray, n_all: int,
                  local: np.ndarray | None = None) -> None:
    """Scatter one discipline's partial columns for ``rows`` (its entries ``local``) into ``partials``."""
    keep = partials.setdefault(name, {})
    for key, c in got.items():
        col = np.asarray(c) if local is None else np.asarray(c)[local]
        keep.setdefault(key, np.zeros(n_all))[rows] = col


def loop_couplings(specs: Mapping, comp: Sequence[str]) -> tuple[list[str], list[str]]:
    """(every output of the loop, the couplings: those outputs a loop discipline reads)."""
    outs = [v for m in comp for v in specs[m].outputs]
    reads = {v for m in comp for v in specs[m].inputs}
    return outs, [v for v in outs if v in reads]


class LoopSolver:
    """Iterates one feedback loop of an MDA; a subclass per method, registered by ``name``.

    ``warm_start``: a loop starts from the couplings its previous MDA converged to (the batch's
    first converged point; a given coupling column still overrides). ``warm`` holds them per loop."""

    name: ClassVar[str] = ""
    auto_warm_start: ClassVar[bool] = False  # what ``warm_start: auto`` means for this method

    def __init__(self, calls: Calls, graph: CouplingGraph, *, tolerance: float = 1e-10,
                 max_iterations: int = 100, relaxation: float = 1.0, guesses: Mapping[str, float] | None = None,
                 warm_start: bool | str = "auto", fuse_downstream: bool = False):
        if not tolerance > 0:
            raise ValueError(f"mda tolerance {tolerance} must be > 0")
        if int(max_iterations) < 1:
            raise ValueError(f"mda max_iterations {max_iterations} must be >= 1")
        if not 0 < relaxation <= 2:
            raise ValueError(f"mda relaxation {relaxation} must be in (0, 2]")
        if warm_start == "tangent" and self.name != "newton":
            raise ValueError(f"mda warm_start tangent needs method newton (the tangent comes from its "
                             f"Jacobian), not {self.name}")
        if not (isinstance(warm_start, bool) or warm_start in ("auto", "tangent")):
            raise ValueError(f"mda warm_start {warm_start!r} must be true, false, auto or tangent")
        if not isinstance(fuse_downstream, bool):
            raise ValueError(f"mda fuse_downstream {fuse_downstream!r} must be true or false")
        self.calls, self.specs, self.graph = calls, calls.specs, graph
        self.tolerance, self.max_iterations = float(tolerance), int(max_iterations)
        self.relaxation = float(relaxation)
        self.guesses = dict(guesses or {})
        self.warm_start = self.auto_warm_start if warm_start == "auto" else bool(warm_start)
        self.fuse_downstream = False
        self.warm: dict[tuple, dict[str, float]] = {}  # loop -> converged couplings of the last MDA

    def guess(self, v: str) -> float:
        """The starting value of a torn coupling (a vector element falls back to its base name)."""
        return self.guesses.get(v, self.guesses.get(base_name(v), 1.0))

    def solve(self, comp: Sequence[str], b: Batch, w: int) -> list[str]:  # pragma: no cover - interface
        """Iterate loop ``comp`` (of wave ``w``) on the good points of ``b``; return the downstream
        disciplines it evaluated on the way (none, unless the method fuses them)."""
        raise NotImplementedError

    def keep_warm(self, comp: Sequence[str], b: Batch, couplings: Sequence[str], converged: list[int]) -> int | None:
        """Remember the couplings of the batch's first converged point (deterministic); return it."""
        if not (converged and self.warm_start):
            return None
        first = min(converged)
        self.warm[tuple(comp)] = {v: float(b.values[v][first]) for v in couplings}
        return first

    def check(self, b: Batch, active: np.ndarray, new: np.ndarray, old: np.ndarray, it: int,
              converged: list[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """After iteration ``it``: (relative change max |new - old| / max(|new|, 1) per point, inf if
        not finite; the points still good; those converged, also appended to ``converged``). A point
        converges when its relative change is within the tolerance and, once 2 L iterations are known
        (L: the loop's outputs, the longest cycle its changes can go round), so is the distance still to go
        that the change implies, change x r / (1 - r), r the contraction per iteration measured over the
        last 2 L: a slow loop's small step is not yet its answer, and iterates running off to infinity by
        steady steps (a loop without a fixed point: r about 1, a user trial) shrink the relative change,
        not the change."""
        with np.errstate(invalid="ignore"):
            change = np.abs(new - old)
            err = np.max(change / np.maximum(np.abs(new), 1.0), axis=0, initial=0.0)
        err = np.where(np.isfinite(err), err, np.inf)
        loop = max(len(new), 2)
        if b.changes is None or b.changes.shape[0] != 2 * loop:
            b.changes = np.zeros((2 * loop, b.ok.size))
        b.changes[it % (2 * loop), active] = np.max(change, axis=0, initial=0.0)  # a ring of the last 2 L
        b.iterations[active] = it
        alive = b.ok[active]
        done = alive & (err <= self.tolerance)
        if it >= 2 * loop and done.any():  # the distance still to go, where the step alone would do
            j = np.flatnonzero(done)
            ring = b.changes[(it - np.arange(2 * loop)) % (2 * loop)][:, active[j]]  # newest first
            recent, before = ring[:loop].max(axis=0), ring[loop:].max(axis=0)
            # r = (recent / before)^(1/L) per iteration; to go: err r / (1 - r) <= tolerance
            r = np.divide(recent, before, out=np.where(recent > 0, np.inf, 0.0), where=before > 0) ** (1.0 / loop)
            done[j] = (r < 1.0) & (err[j] * r <= self.tolerance * (1.0 - r))
        converged.extend(active[done].tolist())
        return err, alive, done

    def not_converged(self, comp: Sequence[str], b: Batch, active: np.ndarray, err: np.ndarray) -> None:
        other = "" if self.name == "newton" else ": mda.method: newton may converge where a fixed-point sweep does not"
        for i, e in zip(active, err):
            why = (f"relative change {e:.3g} > tolerance {self.tolerance:g}{other}" if e > self.tolerance else
                   f"relative change {e:.3g} within the tolerance, but the changes do not shrink fast enough for the "
                   "distance still to go to be: a loop without a fixed point, or one that needs more iterations")
            b.fail(i, "not_converged", f"MDA loop {list(comp)} did not converge in {self.max_iterations} "
                   f"{self.name} iterations ({why})", loop=comp)
