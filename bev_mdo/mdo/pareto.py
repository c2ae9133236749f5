"""Multi-objective optimisation (thesis §4.4, eqs 4-6..4-10) with pymoo's NSGA-II over the MDA.

``MDAProblem`` is a vectorised pymoo ``Problem``: ``_evaluate`` sends the WHOLE population as
ONE batch through ``formulation.analyse`` (the MDF's batched MDA over any Evaluator,
in-process or ROS), so a generation is one wave of requests per discipline. Objectives are
output names, minimised, or ``(name, maximize)`` pairs (a maximised one is negated for pymoo and
reported as itself); constraints are the problem's (normalised, feasible where <= 0), handed to
pymoo as its inequality constraints. An objective with a ceiling (a discipline's
``upper_limit_below``: from there up its value marks a design the physics cannot serve, such as the
0-100 km/h time of one that cannot reach 100 km/h) adds the constraint value < ceiling, so that such
a design is never on a front. The run's judgement of a design beyond its constraints (``batch_check``,
RunSettings.designs_check: a motor that cannot follow the drive cycle, as ``optimize``, ``evaluate`` and ``sweep``
judge it) adds one more constraint, ``CANNOT_FOLLOW_G`` where it rules the design out, else 0. A point the
disciplines could not evaluate gets objectives 1e30 and constraint 1e6 (pymoo's only); it is counted as failed
(``ParetoResult.failed``, the first error kept), never reported as a constraint violation.

Every generation's feasible non-dominated set (a :class:`Front`, with every MDA variable at
its designs, as evaluated) goes to ``on_front(front, final)``; ``bev-mdo pareto`` writes them
to the bag as ParetoFront messages.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from bev_mdo import interrupts
from bev_mdo.mdo.vectors import did_you_mean

FAILED_F = 1e30
FAILED_G = 1e6
CANNOT_FOLLOW_G = 1.0  # the constraint value of a design ``design_check`` rules out: one scale past a limit


def non_dominated(F: np.ndarray) -> np.ndarray:
    """Boolean mask of the rows of F (N, m) not dominated by any other row (minimisation)."""
    F = np.asarray(F, float)
    le = np.all(F[:, None, :] <= F[None, :, :], axis=2)  # le[i, j]: i <= j everywhere
    lt = np.any(F[:, None, :] < F[None, :, :], axis=2)
    dominated = np.any(le & lt, axis=0)  # some i dominates j
    return ~dominated


@dataclass
class Front:
    """The feasible non-dominated designs of one generation, sorted by the first objective."""

    generation: int
    names: list[str]                 # design variables
    objectives: list[str]
    X: np.ndarray                    # (P, n)
    F: np.ndarray                    # (P, m) the objectives as evaluated (a maximised one not negated)
    values: dict[str, np.ndarray]    # every MDA variable at the designs, (P,) each
    evaluations: int                 # design points evaluated so far
    wall_time_s: float               # since the start of the run


@dataclass
class ParetoResult:
    """Final population and its feasible non-dominated front; everything evaluated in ``archive``."""

    names: list[str]                 # design variables
    objectives: list[str]
    X: np.ndarray                    # (P, n) non-dominated feasible designs
    F: np.ndarray                    # (P, m)
    values: dict[str, np.ndarray]    # every MDA variable at the front's designs
    archive_X: np.ndarray            # every evaluated design (E, n)
    archive_F: np.ndarray            # in pymoo's sense: a maximised objective negated, 1e30 where failed
    archive_cv: np.ndarray           # max normalised violation (<= 0 feasible), NaN where the point failed
    generations: int
    evaluations: int
    batches: int
    generation_times_s: list[float] = field(default_factory=list)
    wall_time_s: float = 0.0
    hypervolume: list[float] = field(default_factory=list)  # each generation's front: ``hypervolumes``
    front_sizes: list[int] = field(default_factory=list)  # each generation's front: its designs
    failed: int = 0                  # evaluated designs the disciplines could not evaluate
    first_error: str = ""            # the first of their errors
    cannot_follow: int = 0           # evaluated designs ``design_check`` ruled out (infeasible)
    least_violated: dict | None = None  # with no feasible design: the archive's (``least_violated``)


HV_REFERENCE = 1.1  # the hypervolume's reference point, each objective, in the last front's scale
TINY_FRONT = 10  # designs: on a smaller front a hypervolume growth in per cent says nothing of settling
FROM_LITTLE = 0.25  # an earlier hypervolume below this share of the last one is "from almost nothing"


def hypervolume_reference(objectives) -> dict:
    """What ``hypervolumes`` measures against, for front.json / summary.json beside the hypervolumes."""
    return {"point": [HV_REFERENCE] * len(objectives), "objectives": list(objectives),
            "scale": "each objective as minimised, scaled by the last generation's front: its best 0, its worst 1"}


def hypervolumes(fronts: list[np.ndarray]) -> list[float]:
    """The hypervolume of each generation's front (objectives as minimised) in the last front's scale
    (its best value 0 and worst 1 in each objective; reference point ``HV_REFERENCE`` each, pymoo's HV;
    at most 1.1^m). NaN with no feasible design. A front still gaining several per cent over its last
    generations has not settled."""
    from pymoo.indicators.hv import HV

    last = fronts[-1] if fronts else np.zeros((0, 0))
    if not len(last):
        return [float("nan")] * len(fronts)
    lo, span = last.min(axis=0), np.ptp(last, axis=0)
    span = np.where(span > 0, span, np.maximum(np.abs(lo), 1.0))
    hv = HV(ref_point=np.full(last.shape[1], HV_REFERENCE))
    return [float(hv((F - lo) / span)) if len(F) else float("nan") for F in fronts]


def settling_line(hv: list[float], last: int = 5, sizes: list[int] | None = None) -> str | None:
    """One line: how much the front's hypervolume (``hypervolumes``) grew over its last generations;
    ``sizes``: each generation's front size. No percentage where it would mean nothing: from an earlier
    hypervolume of almost nothing (below ``FROM_LITTLE`` of the last) or on a front of fewer than
    ``TINY_FRONT`` designs (a trial read "+4646.9 %" on fronts of 1 to 13 designs). The advice of more
    generations only where the front grew: not on a front of one design (objectives that fall together) nor
    on one whose hypervolume fell."""
    k = min(last, len(hv) - 1)
    if k < 1 or not np.isfinite(hv[-1]) or hv[-1] <= 0:
        return None
    before, head = hv[-1 - k], f"front hypervolume over the last {k} generations: "
    more = "more --generations (or a larger --pop) would extend the front"
    n = (sizes[-1 - k], sizes[-1]) if sizes is not None and len(sizes) == len(hv) else None
    if n and n[1] == 1:
        return ("the front is one design: the objectives do not trade off over the designs found (it is the best "
                "in every one), so there is no front to extend")
    if not np.isfinite(before):
        return head + f"from no feasible design; still moving: {more}"
    grew, fell = hv[-1] > 1.01 * before, hv[-1] < 0.99 * before
    lost = "; it fell: NSGA-II's population lost part of the front it held (no archive keeps every design found)"
    if n and min(n) < TINY_FRONT:
        return (head + f"{before:.3g} -> {hv[-1]:.3g} on fronts of {n[0]} and {n[1]} designs, too few for a "
                "growth in per cent to say whether the front has settled" + (f"; {more}" if grew else lost if fell
                                                                             else ""))
    if before < FROM_LITTLE * hv[-1]:
        what = "0 (every design outside the last front's range)" if before <= 0 else \
            f"almost nothing ({before:.3g} -> {hv[-1]:.3g} in the last front's scale, no per cent)"
        return head + f"from {what}; the front was still forming: {more}"
    return (head + f"{100 * (hv[-1] / before - 1):+.1f} %"
            + (f"; still moving: {more}" if grew else f"; not settled{lost}" if fell else " (settled: within 1 %)"))


def _pymoo_problem_class():
    from pymoo.core.problem import Problem as PymooProblem

    class MDAProblem(PymooProblem):
        """Vectorised pymoo problem over a formulation's batched ``analyse`` (one batch per call)."""

        def __init__(self, formulation, objectives, ceilings, design_check=None, batch_check=None):
            self.form = formulation
            self.objectives = [name for name, _ in objectives]
            self.signs = np.array([-1.0 if maximize else 1.0 for _, maximize in objectives])
            self.ceilings = [(j, float(ceilings[o])) for j, o in enumerate(self.objectives) if o in ceilings]
            self.design_check, self.batch_check = design_check, batch_check
            prob = formulation.problem
            n_g = len(prob.constraint_rows) + len(self.ceilings) + (batch_check is not None)
            super().__init__(n_var=len(prob.names), n_obj=len(self.objectives), n_ieq_constr=n_g,
                             xl=prob.array("lower"), xu=prob.array("upper"))
            self.batches = 0
            self.evaluations = 0
            self.archive: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
            self.batch_values: list[dict[str, np.ndarray]] = []
            self._where: dict[bytes, tuple[int, int]] = {}  # design row bytes -> (batch, row)
            self.failed, self.first_error, self.cannot_follow = 0, "", 0

        def _evaluate(self, X, out, *args, **kwargs):
            interrupts.check()  # a signal pymoo's bare excepts swallowed stops the run here
            res = self.form.analyse(X)  # the whole population, one batch
            self.batches += 1
            self.evaluations += len(X)
            ok = np.asarray(res.ok, bool)
            F = np.column_stack([np.asarray(res.values[o], float) for o in self.objectives])
            G = np.column_stack([self.form.problem.g(res.values).reshape(len(X), -1)]
                                + [(F[:, j] - c) / abs(c) for j, c in self.ceilings])  # value < ceiling
            F = F * self.signs
            bad = ~ok | ~np.all(np.isfinite(F), axis=1) | ~np.all(np.isfinite(G), axis=1)
            if self.batch_check is not None:  # the run's check beyond the constraints, at each analysed design
                short = ~bad & np.asarray(self.batch_check(res.values), bool)
                G = np.column_stack([G, np.where(short, CANNOT_FOLLOW_G, 0.0)])
                self.cannot_follow += int(short.sum())
            F[bad] = FAILED_F
            G[bad] = FAILED_G
            out["F"] = F
            if G.shape[1]:
                out["G"] = G
            cv = G.max(axis=1) if G.shape[1] else np.zeros(len(X))
            cv[bad] = np.nan  # a failed point has no violation: it is counted as failed
            self._count_failed(bad, ok, res.messages, X)
            self.archive.append((np.array(X, float), F.copy(), cv))
            self.batch_values.append({k: np.asarray(v) for k, v in res.values.items()})
            b = len(self.batch_values) - 1
            for i, row in enumerate(np.asarray(X, float)):
                self._where[row.tobytes()] = (b, i)

        def _count_failed(self, bad, ok, messages, X) -> None:
            if not bad.any():
                return
            self.failed += int(bad.sum())
            if not self.first_error:
                i = int(np.flatnonzero(bad)[0])
                design = ", ".join(f"{n}={v:.6g}" for n, v in zip(self.form.problem.names, X[i]))
                self.first_error = (messages[i] if not ok[i] and messages[i] else
                                    f"a non-finite objective or constraint value at {design}")

        def values_at(self, X) -> dict[str, np.ndarray]:
            """Every MDA variable at already evaluated designs ``X`` (as evaluated; no new batch)."""
            X = np.asarray(X, float).reshape(-1, self.n_var)
            keys = list(self.batch_values[0]) if self.batch_values else []
            out = {k: np.empty(len(X)) for k in keys}
            for i, row in enumerate(X):
                b, j = self._where[row.tobytes()]
                for k in keys:
                    out[k][i] = self.batch_values[b][k][j]
            return out

    return MDAProblem


def objective_pairs(objectives) -> list[tuple[str, bool]]:
    """(name, maximize) of each objective given as a name (minimised) or a (name, maximize) pair."""
    return [(o, False) if isinstance(o, str) else (str(o[0]), bool(o[1])) for o in objectives]


def make_problem(formulation, objectives, ceilings=None, design_check=None, batch_check=None):
    """The pymoo problem of ``formulation`` (an MDF from ``driver.build_formulation``); ``ceilings``:
    {output: value from which up it marks an infeasible design}, a constraint where it is an objective;
    ``batch_check({variable: (N,) values})``: (N,) bool, True where an analysed design is infeasible beyond its
    constraints (one call a generation), one more constraint; ``design_check({variable: value})``: the same
    judgement of one design as the lines why ([] if it is not), for the least violated design."""
    objectives = objective_pairs(objectives)
    missing = [o for o, _ in objectives if o not in _outputs(formulation)]
    if missing:
        raise ValueError(f"objective {missing[0]!r} is not produced by any discipline; "
                         f"{did_you_mean(missing[0], _outputs(formulation))}outputs: "
                         f"{', '.join(sorted(_outputs(formulation)))}")
    if not objectives:
        raise ValueError("at least one objective is needed")
    return _pymoo_problem_class()(formulation, objectives, dict(ceilings or {}), design_check, batch_check)


def _outputs(formulation) -> set[str]:
    mda = getattr(formulation, "mda", None)
    specs = getattr(mda, "specs", {}) or {}
    return {o for s in specs.values() for o in s.outputs}


def _feasible_front(problem, pop) -> tuple[np.ndarray, np.ndarray]:
    """(X, F) of the feasible non-dominated members of a pymoo population (F as minimised)."""
    X, F = pop.get("X"), pop.get("F")
    G = pop.get("G") if problem.n_ieq_constr else np.zeros((len(X), 0))
    feas = np.all(G <= 0, axis=1) & np.all(F < FAILED_F, axis=1)
    X, F = X[feas], F[feas]
    keep = non_dominated(F) if len(F) else np.zeros(0, bool)
    return X[keep], F[keep]


def _front_F(problem, pop) -> np.ndarray:
    return np.array(_feasible_front(problem, pop)[1], float)


def _front(problem, pop, generation: int, wall_time_s: float) -> Front:
    """The feasible non-dominated members of a pymoo population, sorted by the first objective."""
    X, F = _feasible_front(problem, pop)
    F = F * problem.signs  # as evaluated (a maximised objective is not negated)
    order = np.argsort(F[:, 0], kind="stable") if len(F) else np.zeros(0, int)
    X, F = np.array(X[order], float), np.array(F[order], float)
    return Front(generation, list(problem.form.problem.names), list(problem.objectives), X, F,
                 problem.values_at(X), problem.evaluations, wall_time_s)


def least_violated(problem, X, cv) -> dict | None:
    """The evaluated design of least violation among ``X`` (``cv``: their normalised violations, NaN where
    failed) of ``problem`` (``make_problem``'s): ``{"design", "violation" (normalised), "constraints": [{"constraint",
    "output", "value", "limit"}] each it breaks, in the output's own units, "cannot_follow": design_check's
    lines}``; None if every design failed."""
    cv = np.asarray(cv, float)
    if not np.isfinite(cv).any():
        return None
    i = int(np.nanargmin(cv))
    v = {k: float(a[0]) for k, a in problem.values_at(X[i]).items()}
    rows = [(n, ">=" if k == "lower" else "<=", b, (b - v[n]) if k == "lower" else (v[n] - b))
            for n, k, b, _ in problem.form.problem.constraint_rows]
    rows += [(problem.objectives[j], "<", c, v[problem.objectives[j]] - c) for j, c in problem.ceilings]
    return {"design": problem.form.problem.design_dict(X[i]), "violation": float(cv[i]),
            "constraints": [{"constraint": f"{n} {op} {b:g}", "output": n, "value": v[n], "limit": float(b)}
                            for n, op, b, by in rows if by > 0],
            "cannot_follow": list(dict.fromkeys(problem.design_check(v))) if problem.design_check is not None else []}


def run_nsga2(formulation, objectives, *, pop_size: int = 100, generations: int = 30, seed: int = 1,
              on_generation=None, on_front=None, ceilings=None, design_check=None, batch_check=None
              ) -> ParetoResult:
    """NSGA-II (pymoo) for ``generations`` generations of ``pop_size`` designs; deterministic per seed.

    ``on_generation(gen, n_evals, seconds)`` is called after every generation;
    ``on_front(front, final)`` with every generation's :class:`Front` (``final`` True on the
    last one, which is the result's front). Whatever stops the run (a signal, an error), every
    finished generation's front has gone to ``on_front``. ``ceilings``, ``design_check``, ``batch_check``: as
    ``make_problem``."""
    from pymoo.algorithms.moo.nsga2 import NSGA2
    from pymoo.core.callback import Callback
    from pymoo.optimize import minimize

    if pop_size < 4 or generations < 1:
        raise ValueError(f"pop_size must be >= 4 and generations >= 1, got {pop_size}, {generations}")
    problem = make_problem(formulation, objectives, ceilings, design_check, batch_check)
    times: list[float] = []
    t0 = time.perf_counter()
    pending: list[Front] = []  # a generation's front is sent once the next one shows it was not the last
    fronts: list[np.ndarray] = []  # each generation's front, objectives as minimised (hypervolumes)

    class _CB(Callback):
        def __init__(self):
            super().__init__()
            self.t = time.perf_counter()

        def notify(self, algorithm):
            now = time.perf_counter()
            times.append(now - self.t)
            self.t = now
            fronts.append(_front_F(problem, algorithm.pop))
            if on_front:
                if pending:
                    on_front(pending.pop(), False)
                pending.append(_front(problem, algorithm.pop, int(algorithm.n_gen), now - t0))
            if on_generation:
                on_generation(algorithm.n_gen, problem.evaluations, times[-1])

    try:
        res = minimize(problem, NSGA2(pop_size=pop_size, eliminate_duplicates=True), ("n_gen", int(generations)),
                       seed=int(seed), callback=_CB(), verbose=False)
    except BaseException:  # stopped: the last finished generation's front is not the result's, but it is kept
        if on_front and pending:
            on_front(pending.pop(), False)
        raise
    wall = time.perf_counter() - t0
    n_gen = len(times)  # pymoo's n_gen is one ahead once the run has terminated
    front = _front(problem, res.pop, n_gen, wall)
    if on_front:  # res.pop is the last generation's population: this is the pending front
        on_front(front, True)
    aX = np.concatenate([a[0] for a in problem.archive]) if problem.archive else np.zeros((0, problem.n_var))
    aF = np.concatenate([a[1] for a in problem.archive]) if problem.archive else np.zeros((0, problem.n_obj))
    aC = np.concatenate([a[2] for a in problem.archive]) if problem.archive else np.zeros(0)
    return ParetoResult(list(formulation.problem.names), list(problem.objectives), front.X, front.F,
                        front.values, aX, aF, aC, n_gen,
                        problem.evaluations, problem.batches, times, wall, hypervolumes(fronts),
                        [len(F) for F in fronts], problem.failed, problem.first_error, problem.cannot_follow,
                        None if len(front.X) else least_violated(problem, aX, aC))
