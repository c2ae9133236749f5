"""Total derivatives from discipline partials (docs/derivatives.md, "How the engine uses them").

Partials dF_d/d(input) come from a discipline's ``compute_partials`` or, without one, from finite
differences of that discipline alone (:func:`fd_partials`: every such discipline's stencils in ONE
wave through the evaluator). MDF (:func:`mdf_totals`): the direct method, one linear solve per point
of (I - dF/dy) dy/dx = dF/dx over every discipline output y. IDF (:func:`idf_totals`): the totals are
the partials, and the consistency constraints h = (y_target - F(x, y_target)) / s have
dh/d(x, y_target) = (e_target - dF/d(x, y_target)) / s.
"""
from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np

Partials = dict[tuple[str, str], np.ndarray]  # (output, input) -> (N,)
Failed = dict[tuple[str, str], int]  # (output, input) -> points where that finite-difference partial failed


def fd_partials(evaluator: Any, specs: Mapping[str, Any], names: Sequence[str], values: Mapping[str, np.ndarray],
                n: int, step: float = 1e-6, central: bool = False, base_needed: Sequence[str] = (),
                base_outputs: Mapping[str, np.ndarray] | None = None) -> tuple[dict[str, Partials], Failed]:
    """Finite-difference partials of the disciplines ``names`` at the N points of ``values`` (every
    input column, (N,) each). One ``evaluator.evaluate`` call (one wave) evaluates every stencil.

    The step of input v is ``step * max(|v|, 1)``. Forward differences take the discipline's
    outputs in ``values`` as the base point, except for the disciplines in ``base_needed``
    (inside a loop: their last outputs were computed from slightly older inputs), whose base is
    evaluated too. ``base_outputs``: the base outputs where an output's name in ``values`` is another
    discipline's input at another value (IDF: a coupling's target beside what its discipline computed).
    Returns ({discipline: partials}, {(output, input): points where that partial failed}); a failed
    partial is 0."""
    base_outputs = values if base_outputs is None else base_outputs
    calls, plans = [], []
    for name in names:
        spec = specs[name]
        ins = list(spec.inputs)
        k = len(ins)
        if k == 0 or n == 0:
            continue
        base = np.array([np.asarray(values[v], dtype=float)[:n] for v in ins])  # (k, N)
        h = step * np.maximum(np.abs(base), 1.0)  # (k, N)
        blocks = []  # per input j: x + h_j (forward), or x + h_j then x - h_j (central)
        for j in range(k):
            for sign in ((1.0, -1.0) if central else (1.0,)):
                shifted = base.copy()
                shifted[j] += sign * h[j]
                blocks.append(shifted)
        with_base = (name in base_needed) and not central
        if with_base:  # the last block
            blocks.append(base)
        stacked = np.concatenate(blocks, axis=1)  # (k, N * len(blocks))
        batch = {v: stacked[j] for j, v in enumerate(ins)}
        for p in spec.parameters:
            if p in values:
                batch[p] = np.tile(np.asarray(values[p], dtype=float)[:n], len(blocks))
        calls.append((name, batch))
        plans.append((name, ins, h, len(blocks), with_base))
    if not calls:
        return {}, {}
    results = evaluator.evaluate(calls)
    out: dict[str, Partials] = {}
    failed: Failed = {}
    for (name, ins, h, nb, with_base), res in zip(plans, results):
        outs = specs[name].outputs
        Y = {o: np.asarray(res.outputs[o], dtype=float).reshape(nb, n) for o in outs}
        OK = np.asarray(res.ok, dtype=bool).reshape(nb, n)
        part: Partials = {}
        for o in outs:
            if with_base:
                y0, ok0 = Y[o][-1], OK[-1]
            else:
                y0, ok0 = np.asarray(base_outputs[o], dtype=float)[:n], np.ones(n, bool)
            for j, v in enumerate(ins):
                if central:
                    d = (Y[o][2 * j] - Y[o][2 * j + 1]) / (2 * h[j])
                    good = OK[2 * j] & OK[2 * j + 1]
                else:
                    d = (Y[o][j] - y0) / h[j]
                    good = OK[j] & ok0
                if not good.all():
                    failed[(o, v)] = int((~good).sum())
                    d = np.where(good, d, 0.0)
                if np.any(d != 0.0):
                    part[(o, v)] = d
        out[name] = part
    return out, failed


def _index(names: Sequence[str]) -> dict[str, int]:
    return {v: k for k, v in enumerate(names)}


def mdf_totals(outputs: Sequence[str], design: Sequence[str], partials: Mapping[str, Partials],
               n: int) -> dict[str, np.ndarray]:
    """d(output)/d(design) (N, len(design)) for every discipline output, by one linear solve
    (I - dF/dy) dy/dx = dF/dx per point. Inputs that are neither outputs nor design variables
    (fixed parameters) are constants."""
    yi, xi = _index(outputs), _index(design)
    ny, nx = len(outputs), len(design)
    A = np.zeros((n, ny, ny))
    A[:, np.arange(ny), np.arange(ny)] = 1.0
    B = np.zeros((n, ny, nx))
    for part in partials.values():
        for (o, i), col in part.items():
            r = yi.get(o)
            if r is None:
                continue
            if i in yi:
                A[:, r, yi[i]] -= col
            elif i in xi:
                B[:, r, xi[i]] += col
    dy = np.linalg.solve(A, B) if ny else B
    return {v: dy[:, k, :] for v, k in yi.items()}


def idf_totals(outputs: Sequence[str], variables: Sequence[str], partials: Mapping[str, Partials],
               n: int) -> dict[str, np.ndarray]:
    """d(output)/d(variables) (N, len(variables)) when every input of every discipline is an
    optimiser variable or a constant (IDF): the partials themselves."""
    xi = _index(variables)
    out = {v: np.zeros((n, len(variables))) for v in outputs}
    for part in partials.values():
        for (o, i), col in part.items():
            if o in out and i in xi:
                out[o][:, xi[i]] += col
    return out


def unknown_variables(failed: Iterable[tuple[str, str]], variables: Sequence[str], quantities: Iterable[str],
                      specs: Mapping[str, Any]) -> list[str]:
    """The ``variables`` whose totals of the ``quantities`` (objective, constraints, IDF's couplings)
    use a failed partial d output / d input: its input is the variable or, through the disciplines
    of ``specs`` (MDF's chain rule and loop solve), an output downstream of it, and its output is a
    quantity or upstream of one. A failed partial no quantity depends on leaves every total exact.
    IDF passes no ``specs`` ({}): its totals are the partials themselves."""
    readers: dict[str, set[str]] = {}  # v -> outputs of the disciplines reading v
    for spec in specs.values():
        for v in spec.inputs:
            readers.setdefault(v, set()).update(spec.outputs)

    def downstream(v: str) -> set[str]:
        seen, todo = {v}, [v]
        while todo:
            for o in readers.get(todo.pop(), ()):
                if o not in seen:
                    seen.add(o)
                    todo.append(o)
        return seen

    quantities = set(quantities)
    inputs = {v for o, v in failed if downstream(o) & quantities}
    return [x for x in variables if downstream(x) & inputs]


def constraint_jacobian(problem: Any, totals: Mapping[str, np.ndarray], design: Sequence[str],
                        n: int) -> np.ndarray:
    """d g / d vars (N, m, n_vars) of the normalised constraints g (problem.g's rows)."""
    xi = _index(design)
    rows = []
    for name, kind, _bound, scale in problem.constraint_rows:
        if name in totals:
            d = totals[name]
        else:  # a constraint directly on an optimiser variable
            d = np.zeros((n, len(design)))
            if name in xi:
                d[:, xi[name]] = 1.0
        rows.append((-d if kind == "lower" else d) / scale)
    return np.stack(rows, axis=1) if rows else np.zeros((n, 0, len(design)))


def compare_partials(analytic: Partials, fd: Partials, rtol: float = 1e-4, atol: float = 1e-8) -> list[dict]:
    """Entries (output, input, analytic, fd, abs error, rel error, ok) at one point, worst first."""
    rows = []
    for key in sorted(set(analytic) | set(fd)):
        a = float(np.asarray(analytic.get(key, 0.0)).ravel()[0])
        f = float(np.asarray(fd.get(key, 0.0)).ravel()[0])
        err = abs(a - f)
        rel = err / max(abs(a), abs(f), 1e-300) if err else 0.0
        rows.append({"output": key[0], "input": key[1], "analytic": a, "fd": f, "abs_error": err,
                     "rel_error": rel, "ok": bool(err <= atol + rtol * max(abs(a), abs(f)))})
    rows.sort(key=lambda r: (r["ok"], -r["rel_error"]))
    return rows
