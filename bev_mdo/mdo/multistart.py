"""Multi-start: the same optimisation from several start points, to see whether the optimum found is
the best on the sample (``bev-mdo optimize --starts N``).

The starts are a Latin hypercube over the design variables' bounds (scipy.stats.qmc, seeded); each
runs ``driver.run_optimization``, all at once, in lockstep (lockstep.py): the points every running
start asks for at the same step go to the evaluator as one batch per discipline, so over ROS N starts
cost about the round trips of one. Each start's rows are evaluated as they would be alone, so its
result is the one it reaches run by itself (``batched=False`` runs them one after another, for
comparison). Every start's iteration records go to the callback with one running iteration number,
so a bag holds them as one run.

A start **reached the best objective** when its result is feasible (by the run's whole judgement: its
constraints and ``RunSettings.design_check``, a motor that follows the cycle) and its objective is within
``rel_tol`` of the best feasible objective (relative to it, or to ``problem.objective_scale`` where it is
smaller: an optimum of 0), wherever its design is: an objective that does not depend on a variable is met
at many designs. Those of them more than ``design_tol`` of a variable's range from the result's design are
counted apart (``other_designs``): the optimum is not unique.
"""
from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from scipy.stats import qmc

from bev_mdo.mdo.driver import Run, RunResult, run_optimization
from bev_mdo.mdo.evaluator import Evaluator
from bev_mdo.mdo.first_order import OPTIMUM
from bev_mdo.mdo.lockstep import run_lockstep
from bev_mdo.mdo.optimizers import ONE_AT_A_TIME, canonical_name
from bev_mdo.mdo.problem import Problem
from bev_mdo.mdo.settings import RunSettings

REL_TOL = 1e-6     # objective, relative to the best
DESIGN_TOL = 1e-3  # each design variable, as a share of its range
# Every finished start keeps its result and iteration records until the best is chosen (about 40 KB a
# start on leaf_nedc, more with more iterations or variables: 0.4 GB at this bound); --starts 100000000
# asked for a 2.4 GB sample at once and ended in a MemoryError.
MAX_STARTS = 10_000


def check_starts(starts: int) -> None:
    """A one-line ValueError for a start count outside [1, MAX_STARTS]."""
    if starts < 1:
        raise ValueError(f"--starts {starts}: give at least 1")
    if starts > MAX_STARTS:
        raise ValueError(f"--starts {starts}: at most {MAX_STARTS:,} (each finished start's result and iteration "
                         "records are kept until the best is chosen)")


def start_points(problem: Problem, starts: int, seed: int = 0) -> list[dict[str, float]]:
    """``starts`` Latin-hypercube points over the design variables' bounds."""
    check_starts(starts)
    lo, hi = problem.array("lower"), problem.array("upper")
    unit = qmc.LatinHypercube(d=len(lo), seed=seed).random(starts)
    return [problem.design_dict(row) for row in qmc.scale(unit, lo, hi)]


def run_starts(run: Run, evaluator: Evaluator, starts: int | list[dict[str, float]], *, seed: int = 0,
               formulation: str | None = None, optimizer: str | None = None,
               callback: Callable[[dict], Any] | None = None, rel_tol: float = REL_TOL,
               design_tol: float = DESIGN_TOL, batched: bool = True) -> RunResult:
    """The best of ``starts`` optimisations (RunResult of the best start, with the totals of all of
    them and ``multistart`` set); one start is ``run_optimization`` as it is. ``starts``: a count (a
    Latin hypercube of that many points, ``seed``) or the start points themselves (a multi-start
    resumed from each start's last record: ``seed`` is then None in the records and the summary)."""
    t0 = time.perf_counter()
    run = RunSettings.of(run, evaluator)
    problem = run.optimisation_problem()
    if isinstance(starts, int) and starts == 1:
        return run_optimization(run, evaluator, formulation=formulation, optimizer=optimizer, callback=callback)
    if batched and canonical_name(optimizer or run.optimizer.name) in ONE_AT_A_TIME:
        batched = False  # its starts cannot share waves: one after another, each its own batches
    if isinstance(starts, int):
        points = start_points(problem, starts, seed)
    else:
        points, seed = [dict(x0) for x0 in starts], None
    starts = len(points)
    count = [0]

    def renumbered(rec: dict) -> None:  # on one thread: records in the order they were made
        if callback is not None:  # the run's running number (the bag's); the start's own for its progress line
            callback({**rec, "iteration": count[0], "start_iteration": rec["iteration"]})
        count[0] += 1

    def tagged(i: int):  # each record names its start (0-based), so a resume can go on from each one's last record
        return lambda rec: {**rec, "start": (i, starts, seed)}

    if batched:
        def job(i: int, x0: dict[str, float]):
            tag = tagged(i)
            return lambda ev: run_optimization(run, ev, formulation=formulation, optimizer=optimizer, x0=x0,
                                               callback=lambda rec: ev.emit(renumbered, tag(rec)))
        results = list(zip(points, run_lockstep(evaluator, [job(i, x0) for i, x0 in enumerate(points)])))
    else:
        results = [(x0, run_optimization(run, evaluator, formulation=formulation, optimizer=optimizer, x0=x0,
                                         callback=lambda rec, tag=tagged(i): renumbered(tag(rec))))
                   for i, x0 in enumerate(points)]
    span = problem.array("upper") - problem.array("lower")
    close = _close(rel_tol, problem.objective_scale)
    best_i = _best_start([r for _, r in results], -1.0 if problem.maximize else 1.0, span, problem.names, design_tol,
                         close)
    best = results[best_i][1]

    def reached(r: RunResult) -> bool:  # the best objective, at the result's design or another one
        return bool(r.feasible and best.feasible and close(r.objective, best.objective))

    wall = time.perf_counter() - t0
    best.multistart = {
        "starts": starts, "seed": seed, "batched": batched, "best_start": best_i,
        "reached_best": sum(reached(r) for _, r in results),
        "other_designs": sum(reached(r) and not _same_point(r, best, problem.names, span, design_tol)
                             for _, r in results),
        "feasible": sum(bool(r.feasible) for _, r in results), "objective_rel_tol": rel_tol, "design_tol": design_tol,
        "designs_per_s": sum(r.points_evaluated for _, r in results) / max(wall, 1e-12),
        "results": [{"start": i, "x0": x0, "design": r.design, "objective": r.objective, "feasible": r.feasible,
                     "max_violation": r.max_violation, "verdict": r.verdict, "iterations": r.iterations, "reached_best": reached(r)}
                    for i, (x0, r) in enumerate(results)],
    }
    for name in ("mda_evaluations", "points_evaluated", "batches", "gradients", "fd_failures"):
        setattr(best, name, sum(getattr(r, name) for _, r in results))
    best.discipline_evaluations = dict(evaluator.counts)
    best.wall_time_s = wall
    return best


def _close(rel_tol: float, objective_scale: float):
    """``close(f, best)``: ``f`` within ``rel_tol`` of ``best``, relative to it or to ``objective_scale`` where
    that is larger (an optimum of 0: three starts at -4e-12, -6e-12 and 4e-12 of propane's 0 all reached it)."""
    return lambda f, best: abs(f - best) <= rel_tol * max(abs(best), objective_scale)


def _best_start(results: list[RunResult], sign: float, span: np.ndarray, names: list[str],
                design_tol: float, close=None) -> int:
    """The start whose result is the run's: the best feasible objective (feasible by the run's whole judgement,
    driver.design_check included); where several starts reached that point (each design variable within
    ``design_tol`` of its range) or its objective (``close(f, best)``), one whose first-order check verified
    the optimum before one that stopped short of it, then the least violated. One that stopped inside the
    feasibility tolerance but past an active constraint buys a little objective with its violation and
    does not stand for the point the others reached exactly (driver.pick_result's rule within one run).
    With no feasible result, the least violated (one that cannot follow its cycle after those that can, a failed
    end last; ties by objective), as a sweep's best design: the one the infeasible answers then describe."""
    def objective(i: int) -> tuple[float, int]:  # a failed end (NaN) last
        f = sign * results[i].objective
        return (f if f == f else float("inf")), i

    feasible = [i for i, r in enumerate(results) if r.feasible]
    if not feasible:
        def violation(i: int) -> tuple:
            v, r = results[i].max_violation, results[i]
            return bool((getattr(r, "first_order", None) or {}).get("cannot_follow")), v if v == v else float("inf")
        return min(range(len(results)), key=lambda i: (*violation(i), *objective(i)))
    best = min(feasible, key=objective)
    same = [i for i in feasible if _same_point(results[i], results[best], names, span, design_tol)
            or close is not None and close(results[i].objective, results[best].objective)]
    return min(same, key=lambda i: (results[i].verdict != OPTIMUM, results[i].max_violation, *objective(i)))


def _same_point(a: RunResult, b: RunResult, names: list[str], span: np.ndarray, design_tol: float) -> bool:
    """Each design variable of the two results within ``design_tol`` of its range (``span``)."""
    return bool(np.all(np.abs(np.array([a.design[n] - b.design[n] for n in names])) <= design_tol * span))


def summary_line(ms: Mapping[str, Any]) -> str:
    """How many starts reached the best objective (and at other designs), how many ended feasible, for the
    terminal."""
    verdicts = Counter(r["verdict"] for r in ms["results"])
    other = ms.get("other_designs", 0)
    feasible = ms.get("feasible", sum(bool(r["feasible"]) for r in ms["results"]))
    if not feasible:  # "0 of 4 starts reached the best objective", and the result was start 0's
        return (f"multi-start: none of {ms['starts']} starts ended feasible ("
                + ("given start points" if ms["seed"] is None else f"Latin hypercube, seed {ms['seed']}")
                + f"); the result is start {ms['best_start'] + 1}'s, the least violated; verdicts: "
                + ", ".join(f"{n} {v}" for v, n in sorted(verdicts.items(), key=lambda kv: -kv[1])))
    return (f"multi-start: {ms['reached_best']} of {ms['starts']} starts reached the best objective (within "
            f"{ms['objective_rel_tol']:g} relative"
            + (f"; {other} of them at another design, more than {ms['design_tol']:g} of a variable's range from the "
               "result's: the optimum is not unique" if other else "")
            + "; " + ("given start points" if ms["seed"] is None else f"Latin hypercube, seed {ms['seed']}")
            + f"); {feasible} of {ms['starts']} ended feasible; verdicts: "
            + ", ".join(f"{n} {v}" for v, n in sorted(verdicts.items(), key=lambda kv: -kv[1])))
