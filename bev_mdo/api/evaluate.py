"""Designs evaluated through every discipline: one (``design``) or a batch (``batch``), in process
or through the discipline nodes (``Transport``). The core of ``Study.evaluate``/``Study.sweep`` and
of ``bev-mdo evaluate``/``sweep``/``compare``."""
from __future__ import annotations

import sys

import numpy as np

from bev_mdo.api.errors import InputError
from bev_mdo.api.overrides import finite_values
from bev_mdo.api.transport import Evaluating
from bev_mdo.mdo.vectors import did_you_mean


def declared_units(config, parameters=()) -> dict[str, str]:
    """{variable: unit} as the run's disciplines declare them (mdo/units.py): what tables and plots print; beside
    them the built-in model parameters among ``parameters`` (models.params; '' dimensionless): a design's override
    columns, such as load_kg, which no discipline declares as a variable."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.units import run_units
    from bev_mdo.models.params import all_specs

    specs = all_specs()
    return {**{k: "" if specs[k].unit == "-" else specs[k].unit for k in parameters if k in specs},
            **run_units(RunConfig.of(config).disciplines)}


def units_of(config, names) -> dict[str, str]:
    """{name: unit} of ``names`` alone (``declared_units``; a name with no unit is left out): a result's variables,
    a sensitivity's (``--wrt load_kg`` too)."""
    units = declared_units(config, names)
    return {k: units[k] for k in names if k in units}


def axis_label(units: dict | None):
    """``label(name)``: a variable's axis label with its unit as ``units`` declares it, for the plots of
    the runs (drawn with bev_mdo.figures)."""
    from bev_mdo.mdo import units as un

    def label(name: str) -> str:
        return un.label(name, units or {})

    return label


def design(config, given: dict[str, float], transport, caller: str = "bev-mdo evaluate") -> dict:
    """The report of one multidisciplinary analysis (mdo.driver.evaluate_design: design, outputs,
    objective, constraints with margins, feasible, ok, error; ``notes``, only when a discipline has one
    about an output's value, e.g. a design that cannot reach 100 km/h). Design variables not given take their
    initial value; a value outside its bounds is evaluated as given, with a note on stderr (``caller``: its
    prefix, the command or the API's method), and is infeasible whatever its constraints say (as optimize's
    answers call such a point, docs/answers.md; ``notes`` says why), but one the models refuse (outside a
    physical design limit or a parameter's range) is an InputError."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.active import outside_bounds, outside_note
    from bev_mdo.mdo.driver import evaluate_design, feasibility_tolerance

    config = RunConfig.of(config)
    for name, value in given.items():  # t: [1, 2, 0.5] for the vector t was told to use sweep(designs=...)
        if np.ndim(value) and (size := sum(n.startswith(f"{name}[") for n in config.problem.names)):
            raise InputError(f"{name}={value!r}: a vector of {size} elements: give each, {name}[0] .. {name}[{size - 1}]")
    finite_values(given, one="evaluate takes one design, a number per name; sweep(designs=...) evaluates many")
    refuse_outside_model_limits(config, given)
    problem = config.problem
    full = {**{d.name: d.initial for d in problem.design_variables}, **given}
    outside = [outside_note(d, v) for d, v in note_outside_bounds(problem, given, caller)
               if outside_bounds(d, v, feasibility_tolerance(config.settings))]
    with Evaluating(config, transport) as evaluator:
        report = evaluate_design(config.settings, evaluator, full)
    short, notes = notes_of(config, {**problem.parameters, **full}, report["outputs"], found=report)
    notes = outside + notes
    if short or outside:  # not a design the run's energy describes, or off the design space: infeasible
        report["feasible"] = False
    if notes:
        report["notes"] = notes
    report["units"] = declared_units(config, report.get("parameters", {}))
    if config.parameter_set:  # which set the vehicle's values came from
        report["parameter_set"] = config.parameter_set
    return report


def note_outside_bounds(problem, given: dict[str, float], caller: str) -> list[tuple]:
    """Says on stderr, one note each prefixed with ``caller``, the values of ``given`` outside their design
    variable's bounds: evaluated as given (evaluate, check-totals, check-partials), but a user should know the
    point is off the design space. Returns those (DesignVariable, value)."""
    out = []
    for d in problem.design_variables:
        v = given.get(d.name)
        if v is not None and not d.lower <= v <= d.upper:  # (a number: finite_values)
            print(f"{caller}: note: {d.name} = {v:.12g} is outside its bounds [{d.lower:g}, {d.upper:g}] "
                  "(evaluated as given)", file=sys.stderr)
            out.append((d, v))
    return out


def notes_of(config, design: dict, outputs: dict, found: dict | None = None) -> tuple[bool, list[str]]:
    """(whether the one design cannot follow its drive cycle, its notes: that, what its outputs mean
    (``design_notes``; ``found``: as there) and where the follow check does not run)."""
    from bev_mdo.config import RunConfig
    from bev_mdo.disciplines.energy import follow_notes

    short, unchecked = follow_notes(RunConfig.of(config).disciplines, {**design, **outputs})
    return bool(short), short + design_notes(config, {**design, **outputs}, found) + unchecked


def design_notes(config, values: dict, found: dict | None = None) -> list[str]:
    """What an output's value at one design (``values``: its inputs and outputs) means where it is not a
    measurement, as its discipline says (``notes``): e.g. the 0-100 km/h time of a design that cannot reach
    100 km/h, or one the pack's power limits (its ``battery_limit``, evaluated once for both: the note, and
    ``found["accel_battery_limit"]`` when ``found``, evaluate's report, is given)."""
    from bev_mdo.config import RunConfig

    notes = []
    for d in RunConfig.of(config).disciplines:
        limit = getattr(d, "battery_limit", lambda _: None)(values) or {}
        notes += [*(getattr(d, "notes", None) or (lambda _: []))(values), *filter(None, [limit.pop("note", None)])]
        if limit and found is not None:
            found["accel_battery_limit"] = limit
    return notes + platform_notes(config, values)


def platform_notes(config, values: dict) -> list[str]:
    """The note of a fitted set's two-speed loss (disciplines.common.platform_loss_note) where ``values`` (one
    design's or a batch's) set gear_count 2 that the config alone does not (its load gave the note then) and
    not the loss itself."""
    from bev_mdo.config import RunConfig
    from bev_mdo.disciplines.common import platform_loss_note

    config = RunConfig.of(config)
    p = config.problem
    own = "gear_count" in p.names or np.any(np.asarray({**config.vehicle, **p.parameters}.get("gear_count", 1.0)) == 2)
    if own or "two_speed_efficiency_loss" in values or not np.any(np.asarray(values.get("gear_count", 1.0)) == 2):
        return []
    return [n for n in [platform_loss_note(config.data.get("vehicle"))] if n]


def ceilings(config) -> dict[str, tuple[float, str]]:
    """{output: (ceiling, what it means)} of the run's disciplines (their ``upper_limit_below``): from the
    ceiling up the output marks a design the physics cannot serve, not a value of the quantity."""
    from bev_mdo.config import RunConfig

    return {o: c for d in RunConfig.of(config).disciplines for o, c in (getattr(d, "upper_limit_below", None) or {}).items()}


def at_ceiling(ceiling_map: dict, outputs: dict) -> dict[str, tuple[int, int, float, str]]:
    """{output: (values at or above its ceiling, values, ceiling, meaning)} for each output of a batch with
    any (``ceiling_map``: ``ceilings``)."""
    counts = {}
    for name, (ceiling, meaning) in ceiling_map.items():
        y = np.atleast_1d(np.asarray(outputs.get(name, []), dtype=float))
        if (k := int(np.sum(y >= ceiling))):
            counts[name] = (k, y.size, ceiling, meaning)
    return counts


def ceiling_notes(config, outputs: dict, of: str = "designs") -> list[str]:
    """One line per output of a batch with values at or above its ceiling (``ceilings``): how many."""
    return [f"{name}: {k} of {n} {of} at or above {ceiling:g} ({meaning}): not values of the quantity"
            for name, (k, n, ceiling, meaning) in at_ceiling(ceilings(config), outputs).items()]


def refuse_outside_model_limits(config, values) -> None:
    """InputError (one line) for a value no built-in model of the run can evaluate: a motor of -5 kW, a
    glider of -100 kg (config.disciplines.check_model_limits), which gave a table of NaN and exit 1."""
    from bev_mdo.config.disciplines import check_model_limits
    from bev_mdo.config.sections import check_gear_order_per_design

    try:
        check_model_limits(config.disciplines, values)
    except ValueError as exc:
        raise InputError(f"{exc}; such a design cannot be evaluated") from None
    try:
        check_gear_order_per_design(config.vehicle, config.problem, values)
        if isinstance(config.data.get("vehicle"), dict):  # motor_rear_kw on SM-SA: "did you mean 'motor_kg_per_kw'?"
            from bev_mdo.models.params import vehicle_choice
            from bev_mdo.models.topology import check_design_variables

            check_design_variables(vehicle_choice(config.data["vehicle"], "topology"),
                                   [k for k in values if k not in config.problem.names])
    except ValueError as exc:
        raise InputError(str(exc)) from None


def check_names(names, problem, params) -> None:
    """InputError unless every name is a design variable or one of the disciplines' ``params``."""
    unknown = [k for k in names if k not in problem.names and k not in params]
    if unknown:
        raise InputError(f"unknown names {unknown}; {did_you_mean(unknown[0], [*problem.names, *params])}"
                         f"design variables: {problem.names}, parameters: {sorted(params)}")


FIRST_CHUNK_ROWS = 1024  # the first chunk of a batch over ROS; the next ones sized from its measured rate


def run_in_chunks(mda, cols: dict[str, np.ndarray], n: int, timeout_s: float | None):
    """``mda.run(cols)`` for `n` designs; over ROS (`timeout_s`: ros.timeout_s) in consecutive chunks, each sized
    from the rate measured so far to take about a quarter of ``timeout_s``, so that no request outlasts its
    timeout and is re-sent to a node still busy with it (docs/doe.md). Each chunk starts from the loop
    solver's warm start of the whole batch, and no chunk has a single row (FLOW_MIN_ROWS): the results are
    those of one batch."""
    if timeout_s is None or n <= FIRST_CHUNK_ROWS:
        return mda.run(cols)
    import dataclasses
    import time

    from bev_mdo import interrupts
    from bev_mdo.mdo.mda.base import MDAResult

    warm, parts, start, rows = dict(mda.solver.warm), [], 0, FIRST_CHUNK_ROWS
    while start < n:
        stop = n if n - (start + rows) < 2 else start + rows
        mda.solver.warm = dict(warm)
        t = time.monotonic()
        parts.append((start, mda.run({k: v[start:stop] for k, v in cols.items()})))
        rows = max(2, min(65536, int((stop - start) / max(time.monotonic() - t, 1e-3) * timeout_s / 4)))
        start = stop
        interrupts.check()  # a Ctrl-C swallowed on the way stops the batch here
    return MDAResult({k: np.concatenate([r.values[k] for _, r in parts]) for k in parts[0][1].values},
                     np.concatenate([r.ok for _, r in parts]),
                     [e if e is None else dataclasses.replace(e, point=e.point + a) for a, r in parts for e in r.errors],
                     np.concatenate([r.iterations for _, r in parts]))


def batch(config, designs: dict[str, np.ndarray], transport) -> dict:
    """One batch of MDAs: {design: {k: array}, outputs: {k: array}, margins: {c: array}, violation: the
    largest normalised violation (inf: failed), feasible: bool array, ok: bool array, outside: each design's notes
    of values outside their bounds (evaluated as given, infeasible), errors: [str], objective, problem, units}
    (``designs`` may set model parameters too; variables not given keep their initial value)."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.active import outside_bounds, outside_note
    from bev_mdo.mdo.driver import _mda, feasibility_tolerance

    finite_values(designs)
    config = RunConfig.of(config)
    problem = config.problem
    n = len(next(iter(designs.values())))
    cols = {d.name: np.full(n, d.initial) for d in problem.design_variables}
    cols.update({k: np.full(n, float(v)) for k, v in problem.parameters.items()})
    with Evaluating(config, transport, announce=True) as evaluator:
        mda = _mda(config.settings, evaluator, problem)
        check_names(designs, problem, {p for s in mda.specs.values() for p in s.parameters})
        refuse_outside_model_limits(config, designs)
        cols.update({k: np.asarray(v, dtype=float) for k, v in designs.items()})
        res = run_in_chunks(mda, cols, n, getattr(getattr(evaluator, "inner", None), "timeout_s", None))  # ROS only
    outputs = {v: np.asarray(res.values[v], dtype=float) for s in mda.specs.values() for v in s.outputs}
    margins = {c.name: np.min([np.full(n, np.inf), *((outputs[c.name] - b) * (1.0 if kind == "lower" else -1.0)
                                                     for kind, b, _ in c.rows(monitored=True))], axis=0)
               for c in problem.constraints}
    g = problem.g(outputs)  # normalised as the optimiser's constraints (and its feasibility rule); NaN: violated
    violation = np.maximum(np.where(res.ok, 0.0, np.inf), np.where(np.isfinite(g), g, np.inf).max(axis=1, initial=0.0))
    # off the design space (a --list row, a --design, a --vary range past a bound): evaluated as given, as evaluate
    # does, and infeasible whatever the constraints say; each design's lines under "outside". Its distance past the
    # bound, over the bounds' span (active.outside_bounds' measure), counts in its violation: a sweep record of such
    # a design said max violation 0 and infeasible, without a reason
    tol = feasibility_tolerance(config.settings)
    for d in problem.design_variables:
        past = np.maximum(d.lower - cols[d.name], cols[d.name] - d.upper) / (d.upper - d.lower)
        violation = np.maximum(violation, np.where(np.isnan(past), np.inf, past))
    feasible = violation <= tol
    beyond = [[d for d in problem.design_variables if outside_bounds(d, cols[d.name][i], tol)] for i in range(n)]
    outside = [[outside_note(d, cols[d.name][i]) if d in far else  # within the tolerance: feasible, as in evaluate
                f"{d.name} = {cols[d.name][i]:.12g} is outside its bounds [{d.lower:g}, {d.upper:g}] (evaluated as given)"
                for d in problem.design_variables if not d.lower <= cols[d.name][i] <= d.upper]
               for i, far in enumerate(beyond)]
    notes = ceiling_notes(config, outputs) + platform_notes(config, designs)
    for group in ([i for i in range(n) if beyond[i]], [i for i in range(n) if outside[i] and not beyond[i]]):
        if group:  # the first design of each: infeasible (beyond the tolerance), then within it
            i, more = group[0], f" (and {len(group) - 1} more)" if len(group) > 1 else ""
            notes.append(f"design {i + 1}{more}: " + (outside_note(beyond[i][0], cols[beyond[i][0].name][i])
                                                      if beyond[i] else outside[i][0]))
    from bev_mdo.disciplines.energy import follow_counts

    short, unchecked = follow_counts(config.disciplines, {**cols, **outputs})  # cannot follow: infeasible, whatever the constraints
    if short.any():
        feasible &= ~short
        notes.append(f"{int(short.sum())} of {n} designs cannot follow the drive cycle (their motor falls short of "
                     "the drive force or over its speed limit): infeasible")
    if unchecked.any():
        notes.append(f"{int(unchecked.sum())} of {n} designs: whether the motor can follow the cycle is not checked "
                     "for their gearbox or topology (the check covers single-speed SM-SA)")
    return {"design": {k: cols[k] for k in [*problem.names, *[k for k in designs if k not in problem.names]]},
            "outputs": outputs, "margins": margins, "violation": violation, "feasible": feasible,
            "ok": np.asarray(res.ok, bool), "outside": outside,
            "errors": res.messages, "objective": problem.objective, "problem": problem,
            "units": declared_units(config, designs), "notes": notes}
