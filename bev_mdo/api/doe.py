"""Designs of experiments for ``bev-mdo sweep --doe``, their plots and their bag.

``sample(method, bounds, n, seed)`` draws designs over the design variables' bounds with
scipy.stats.qmc: ``lhs`` (Latin hypercube), ``sobol`` (scrambled Sobol' sequence, n a power of 2),
``halton`` (scrambled Halton) or ``full`` (full factorial, n levels per variable: n^d designs).
``record(bag_dir, ...)`` writes one IterationRecord per design into an MCAP bag (the run's config in
its metadata), so ``history``/``report`` read a sweep like a run.
"""
from __future__ import annotations

import itertools
import time
from pathlib import Path

import numpy as np

from bev_mdo.api.errors import InputError
from bev_mdo.figures import styled, subplots

METHODS = ("lhs", "sobol", "halton", "full")


def sample(method: str, bounds: dict[str, tuple[float, float]], n: int, seed: int | None = None) -> dict[str, np.ndarray]:
    """{name: values} of ``n`` designs (``full``: n levels per variable) within ``bounds``."""
    from scipy.stats import qmc

    names = list(bounds)
    d = len(names)
    if not names:
        raise InputError("--doe: no design variable left to vary (all are fixed with --set)")
    if n < 1 or (method == "full" and n < 2):
        raise InputError(f"--samples {n}: must be >= {2 if method == 'full' else 1}")
    lo = np.array([bounds[k][0] for k in names], dtype=float)
    hi = np.array([bounds[k][1] for k in names], dtype=float)
    if method == "full":
        if n ** d > 1_000_000:
            raise InputError(f"--doe full --samples {n}: {n}^{d} = {n ** d} designs is too many; use lhs or sobol")
        unit = np.array(list(itertools.product(*[np.linspace(0.0, 1.0, n)] * d)), dtype=float)
    elif method == "lhs":
        unit = qmc.LatinHypercube(d, rng=seed).random(n)
    elif method == "sobol":
        m = int(round(np.log2(n)))
        if 2 ** m != n:
            raise InputError(f"--doe sobol --samples {n}: must be a power of 2 (e.g. {2 ** max(m, 0)} or "
                             f"{2 ** (m + 1)}) to keep the sequence balanced")
        unit = qmc.Sobol(d, scramble=True, rng=seed).random_base2(m)
    elif method == "halton":
        unit = qmc.Halton(d, scramble=True, rng=seed).random(n)
    else:
        raise InputError(f"--doe {method!r}: allowed: {', '.join(METHODS)}")
    X = lo + unit * (hi - lo)
    return {k: X[:, j] for j, k in enumerate(names)}


def batch(problem, doe: str | None, samples: int, seed: int | None, given: dict | None,
          fixed: dict[str, float], fixed_flag: str = "fixed") -> dict[str, np.ndarray]:
    """The designs of a sweep, {name: values}: the ``given`` columns (a grid or a list), else a ``doe``
    over the bounds of the design variables not ``fixed``; the ``fixed`` values as constant columns.
    InputError for no design, or a name both given and fixed (``fixed_flag`` names that input)."""
    if given is None:
        given = sample(doe, {d.name: (d.lower, d.upper) for d in problem.design_variables if d.name not in fixed},
                       samples, seed)
    n = len(next(iter(given.values()))) if given else 0
    if not n:
        raise InputError("no design to evaluate: give each varied name at least one value")
    for k, v in fixed.items():
        if k in given:
            raise InputError(f"{fixed_flag} {k} is also varied")
    return {**given, **{k: np.full(n, v) for k, v in fixed.items()}}


@styled
def plot_scatter(result: dict, output: str, varied: list[str], path: Path, method: str):
    """One PNG: ``output`` against each varied variable (one panel each), feasible points filled,
    infeasible red x, constraint limits dashed."""
    from bev_mdo.api.evaluate import axis_label

    label = axis_label(result.get("units"))
    problem, y, feas = result["problem"], result["outputs"][output], result["feasible"]
    ncols = min(len(varied), 3)
    nrows = -(-len(varied) // ncols)
    fig, axes = subplots(nrows, ncols, figsize=(3.6 * ncols + 0.6, 3.2 * nrows + 0.6), squeeze=False,
                             sharey=True, layout="constrained")
    for ax, name in zip(axes.flat, varied):
        x = result["design"][name]
        ax.plot(x[feas], y[feas], "o", color="C0", ms=3, alpha=0.7, label="feasible")
        ax.plot(x[~feas], y[~feas], "x", color="C3", ms=4, alpha=0.7, label="infeasible")
        for c in problem.constraints:
            if c.name == output:
                for b in (c.lower, c.upper):
                    if b is not None:
                        ax.axhline(b, color="C3", ls="--", lw=1.0)
        ax.set_xlabel(label(name), fontsize=8)
        ax.grid(alpha=0.3)
    for ax in axes.flat[len(varied):]:
        ax.set_visible(False)
    for row in axes:
        row[0].set_ylabel(label(output), fontsize=8)
    axes.flat[0].legend(fontsize=7, loc="best")
    fig.suptitle(f"{label(output)}: {len(y)} designs ({method})", fontsize=10)
    fig.savefig(path, dpi=100)
    return fig


def record(bag_dir: Path, config, result: dict, method: str, transport: str, fixed: dict | None = None) -> Path:
    """The sweep as a bag: one IterationRecord per design (iteration = design index, optimizer =
    the DOE method), the effective config in the metadata, and ``fixed`` (the ``--set`` values) as its
    ``fixed`` entry (JSON), which ``resume`` keeps fixed."""
    import json
    import uuid

    from bev_mdo.api.runbag import InProcessBag

    problem, n = result["problem"], len(result["feasible"])
    # the count it will hold: a bag cut short (a signal while it is written) is said to be part of the sweep
    bag = InProcessBag(Path(bag_dir), config, uuid.uuid4().hex[:16], transport=transport, designs=str(n),
                       **({"fixed": json.dumps(fixed)} if fixed else {}))
    t0 = time.perf_counter()
    try:
        for i in range(n):
            violation = float(result["violation"][i])  # normalised, as in an optimisation's records (nan: failed)
            ok = bool(result["ok"][i])  # a failed design has no values in its record (IterationRecord.msg), even
            # where the MDA kept an output that does not depend on the failure (a 21 t design's cost)

            def value(name):
                return float(result["outputs"][name][i]) if ok else float("nan")

            bag({"iteration": i, "formulation": "doe", "optimizer": method,
                 "design": {k: float(v[i]) for k, v in result["design"].items()},
                 "objective_name": problem.objective, "objective": value(problem.objective),
                 "constraints": {c.name: value(c.name) for c in problem.constraints},
                 "max_violation": violation if np.isfinite(violation) else float("nan"),
                 "feasible": bool(result["feasible"][i]), "mda_evaluations": i + 1,
                 "wall_time_s": time.perf_counter() - t0})
    finally:
        bag.close()
    return Path(bag_dir)
