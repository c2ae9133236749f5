"""Sensitivities of the objective and every constrained output: local (normalised first and second
order at a design, bev_mdo.mdo.sensitivity; thesis eq 5-4 and 5-5) and global over the bounds
(SALib). The core of ``Study.sensitivity``/``Study.global_sensitivity`` and ``bev-mdo sensitivity``.

Global: SALib draws the designs and estimates the indices; every design is evaluated in ONE batch (one
evaluator call: in process, or one request wave per graph level over ROS).

* ``sobol``: Saltelli's sampling of Sobol' sequences, N (D + 2) designs for D variables; first-order
  (S1) and total (ST) Sobol' indices of every output, each with its bootstrap confidence interval.
* ``morris``: N trajectories of D + 1 designs on a 4-level grid; mu* (the mean absolute elementary
  effect, in the output's unit) with its confidence interval, and sigma (interactions and
  non-linearity).
Variables not analysed (and model parameters) keep their value at the design point (``--at``).
"""
from __future__ import annotations

import numpy as np

from bev_mdo.api.errors import InputError
from bev_mdo.api.evaluate import units_of  # (Study's and the CLI's too)
from bev_mdo.api.overrides import finite_values
from bev_mdo.api.transport import Evaluating, Transport
from bev_mdo.mdo.vectors import did_you_mean

METHODS = ("sobol", "morris")


def run(config, at: dict | None = None, wrt: list[str] | None = None, transport=None, *,
        global_method: str | None = None, order: int = 2, rel_step: float | None = None, method: str = "central",
        samples: int | None = None, seed: int = 1, conf_level: float = 0.95):
    """Local: (mdo.sensitivity.Sensitivities, outputs, point, problem); global (``global_method``
    sobol or morris): the JSON-ready report of ``analyse``."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.mdo.sensitivity import sensitivities

    if global_method is not None and global_method not in METHODS:  # before anything starts
        raise InputError(f"--global {global_method!r}: allowed: {', '.join(METHODS)}")
    config = RunConfig.of(config)
    finite_values(at or {}, "--at", one="the design the sensitivities are taken at, a number per name")

    if method == "complex":  # the MDA casts every input to float64 (the discipline interface)
        raise InputError("--method complex: the multidisciplinary analysis passes float64 values between "
                         "disciplines (in process and over ROS), so a complex step cannot pass through it, "
                         "whatever the disciplines; use --method central (the default)")
    defaults = None
    if Transport.of(transport).uses_ros:  # a remote declaration names parameters, not their values
        local = InProcessEvaluator(config.disciplines)
        defaults = {k: v for spec in local.specs.values() for k, v in spec.parameters.items()}
        local.close()
    with Evaluating(config, transport, node_name="bev_mdo_sensitivity") as ev:
        fun, point, bounds, outputs, problem = build_batch(config, ev, defaults, local=not global_method)
        for k, v in (at or {}).items():
            if k not in point:
                raise InputError(f"--at: unknown name {k!r}; {did_you_mean(k, point)}"
                                 f"design variables: {', '.join(problem.names)}; "
                                 f"parameters: {', '.join(n for n in point if n not in problem.names)}")
            point[k] = float(v)
        wrt = list(wrt or []) or list(problem.names)
        for i, k in enumerate(wrt):
            if k not in point:
                raise InputError(f"--wrt: unknown variable or parameter {k!r}; {did_you_mean(k, point)}"
                                 f"known: {', '.join(point)}")
            if k in wrt[:i]:  # its rows and columns were printed twice
                raise InputError(f"--wrt: {k!r} named twice")
        if global_method:
            varied = [k for k in (at or {}) if k in wrt]  # their --at values were ignored without a word
            if varied:
                raise InputError(f"--at {', '.join(varied)}: varied over the bounds by --global; --at fixes only "
                                 "the variables not in --wrt")
            samples = (1024 if global_method == "sobol" else 64) if samples is None else samples
            from bev_mdo.api.evaluate import ceilings

            rep = analyse(global_method, fun, point, bounds, wrt, outputs, samples, seed, conf_level,
                          design=list(problem.names), ceilings=ceilings(config))
            rep["units"] = units_of(config, [*wrt, *outputs])
            return rep
        from bev_mdo.api.evaluate import note_outside_bounds, refuse_outside_model_limits
        from bev_mdo.config.disciplines import model_limits

        refuse_outside_model_limits(config, at or {})  # a design no model evaluates: one line, as evaluate's
        outside = {d.name for d, _ in note_outside_bounds(problem, point, "bev-mdo sensitivity")}  # taken as given
        room = {k: model_limits(config.disciplines, k) for k in outside}  # there the models' limits bound the steps
        s = sensitivities(fun, point, wrt=wrt, order=order, rel_step=rel_step, method=method,
                          bounds={**_model_limits(point, problem.names), **{k: r[:2] for k, r in room.items() if r},
                                  **{k: b for k, b in bounds.items() if k not in outside}})
    return s, outputs, point, problem


def _model_limits(point: dict, design: list[str]) -> dict[str, tuple[float, float]]:
    """The model limits of the built-in parameters at the point (models.params): a step goes one-sided at
    one (the stencil of load_kg = 1000, its upper limit, failed at 1000.1: exit 7)."""
    from bev_mdo.models.params import all_specs

    specs = all_specs()
    return {k: (specs[k].lower, specs[k].upper) for k, v in point.items()
            if k not in design and k in specs and specs[k].lower <= v <= specs[k].upper}


def to_dict(s, outputs, units: dict | None = None) -> dict:
    """The JSON of a local sensitivity ``s``; ``units`` (``units_of``): each wrt variable's and output's unit, those
    of ``step`` and of ``first_order.*.derivative`` (the output's per the variable's). ``second_order.*.labels``:
    the coupling label (NC/MC/SC/VSC) of each pair of variables, null on the diagonal (one variable's own
    curvature is no coupling, as the printed legend says), "" where S' is undefined (the output is 0)."""
    d = {"wrt": list(s.names), "point": s.point, "method": s.method, "step": s.step.tolist(),
         "n_evaluations": s.n_evaluations, "n_batches": s.n_batches, "one_sided": list(s.one_sided),
         "values": s.values, "first_order": {}, "second_order": {}}
    for k in outputs:
        d["first_order"][k] = {"normalised": s.first[k].tolist(), "error": s.first_error[k].tolist(),
                               "derivative": s.gradient[k].tolist()}
        if s.second is not None:
            labels = s.labels(k)
            np.fill_diagonal(labels, None)  # a label is a coupling's, of two variables
            d["second_order"][k] = {"normalised": s.second[k].tolist(), "error": s.second_error[k].tolist(),
                                    "labels": labels.tolist()}
    return d if units is None else {**d, "units": units}


def build_batch(config, evaluator, param_defaults=None, local=False):
    """(fun, nominal point, bounds, outputs, problem) for the MDA of ``config`` over ``evaluator``.
    ``fun(X)`` takes columns in the order of the returned point (design variables, then every
    overridable model parameter) and returns the objective and constrained outputs; ``local``: its batches are a
    local stencil (row 0 the design), which a failure's advice fits."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.driver import build_formulation

    form = build_formulation(RunConfig.of(config).settings, evaluator, "mdf")
    problem, mda = form.problem, form.mda
    params: dict[str, float] = {}
    for spec in mda.specs.values():
        for k, v in spec.parameters.items():
            v = float(v)
            if np.isnan(v) and param_defaults and k in param_defaults:
                v = float(param_defaults[k])  # a remote declaration names parameters, not their values
            params.setdefault(k, v)
    own = dict(params)  # the disciplines' own values: a column equal to one is left out (below)
    params.update(problem.parameters)
    point = {**dict(zip(problem.names, problem.x0().tolist())), **params}
    bounds = {v.name: (v.lower, v.upper) for v in problem.design_variables}
    outputs = [problem.objective] + [c.name for c in problem.constraints if c.name != problem.objective]
    names = list(point)

    def fun(X):
        # A model parameter sent as a column is evaluated design by design (a per-row model); one that
        # keeps the discipline's own value everywhere is left out, so the batch stays vectorised.
        cols = {k: X[:, j] for j, k in enumerate(names)
                if not (k in own and k not in problem.parameters and np.all(X[:, j] == own[k]))}
        res = mda.run(cols)
        if not np.all(res.ok):  # the run failed, not the user's input (a global sample has no stencil)
            from bev_mdo.api.errors import ModelFailed

            i = int(np.flatnonzero(~np.asarray(res.ok))[0])
            at = ", ".join(f"{k}={X[i, j]:.6g}" for j, k in enumerate(names) if k in problem.names)
            why = ("the indices need a value at every one: narrow the bounds to where it answers" if not local else
                   "the design itself fails: move it (--at) to where the model answers" if i == 0 else
                   "a step from the design fails: move it (--at) away from where the model gives none, or shorten "
                   "the steps (--rel-step)")
            raise ModelFailed(f"the model failed at {int((~np.asarray(res.ok)).sum())} of the {len(X)} "
                              f"{'points of the local stencil' if local else 'sampled points'} ({why}); first "
                              f"at {at}: {res.errors[i].message.splitlines()[0] if res.errors[i] else 'no value'}")
        return {k: res.values[k] for k in outputs}
    return fun, point, bounds, outputs, problem


def analyse(method: str, fun, point: dict, bounds: dict[str, tuple[float, float]], names: list[str],
            outputs: list[str], samples: int, seed: int, conf_level: float = 0.95,
            num_resamples: int = 1000, design: list[str] | None = None, ceilings: dict | None = None) -> dict:
    """The indices of every output (JSON-ready). ``fun(X)`` evaluates rows of every column of
    ``point`` and returns {output: values}; it is called once, with every design. ``design``: the
    design variables (those not analysed are reported as fixed; default: every name of ``point``).
    ``ceilings`` (api.evaluate.ceilings): an output with samples at or above its ceiling gets
    ``at_ceiling`` (how many) and a note, for its indices then describe where the designs the physics
    cannot serve lie more than the quantity."""
    if not names:
        raise InputError("--global: no design variable to analyse")
    missing = [k for k in names if k not in bounds]
    if missing:
        raise InputError(f"--global: {missing[0]!r} has no bounds (only design variables can be analysed globally)")
    if samples < 2:
        raise InputError(f"--samples {samples}: must be >= 2")
    if not 0 < conf_level < 1:
        raise InputError(f"--conf-level {conf_level}: must be in (0, 1)")
    spec = {"num_vars": len(names), "names": list(names), "bounds": [list(map(float, bounds[k])) for k in names]}
    if method == "sobol":
        from SALib.sample import sobol as sampler

        m = int(round(np.log2(samples)))
        if 2 ** m != samples:
            raise InputError(f"--global sobol --samples {samples}: must be a power of 2 (e.g. {2 ** m} or "
                             f"{2 ** (m + 1)}) for the Sobol' sequence's balance")
        X = sampler.sample(spec, samples, calc_second_order=False, scramble=True, seed=seed)
    else:
        from SALib.sample import morris as sampler

        X = sampler.sample(spec, samples, num_levels=4, seed=seed)
    cols = list(point)
    full = np.tile(np.array([point[k] for k in cols], dtype=float), (len(X), 1))
    for j, k in enumerate(names):
        full[:, cols.index(k)] = X[:, j]
    values = fun(full)
    from bev_mdo.api.evaluate import at_ceiling

    over = at_ceiling(ceilings or {}, values)
    report = {"method": method, "variables": list(names), "bounds": {k: list(bounds[k]) for k in names},
              "fixed": {k: float(point[k]) for k in (design if design is not None else point) if k not in names},
              "samples": samples, "seed": seed,
              "conf_level": conf_level, "n_evaluations": int(len(X)), "outputs": {}}
    for out in outputs:
        y = np.asarray(values[out], dtype=float)
        if not np.isfinite(y).all() or np.ptp(y) == 0.0:
            report["outputs"][out] = {"constant": True}
            continue
        at, _, ceiling, meaning = over.get(out, (0, 0, np.inf, ""))
        if at:
            report.setdefault("notes", []).append(
                f"{out}: {at} of {y.size} samples at or above {ceiling:g} ({meaning}); its indices describe "
                "where those designs lie more than the quantity: narrow the bounds (--bound) to designs that have it")
        if method == "sobol":
            from SALib.analyze import sobol

            r = sobol.analyze(spec, y, calc_second_order=False, num_resamples=num_resamples,
                              conf_level=conf_level, seed=seed)
            report["outputs"][out] = {k: np.asarray(r[k], float).tolist() for k in ("S1", "S1_conf", "ST", "ST_conf")}
        else:
            from SALib.analyze import morris

            r = morris.analyze(spec, X, y, num_resamples=num_resamples, conf_level=conf_level, num_levels=4, seed=seed)
            report["outputs"][out] = {k: np.asarray(r[k], float).tolist() for k in ("mu", "mu_star", "mu_star_conf", "sigma")}
        if at:
            report["outputs"][out]["at_ceiling"] = at
    return report


