"""A run's disciplines: built from the config's ``disciplines`` list (or the built-in defaults),
checked against the problem, named and listed for the nodes that serve them."""
from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from bev_mdo.config.sections import SIZED_VARIABLE
from bev_mdo.mdo.discipline import options_dict
from bev_mdo.mdo.user_class import load_class, read_options
from bev_mdo.mdo.units import attach_units
from bev_mdo.mdo.vectors import wrap
from bev_mdo.models.common import DESIGN_LIMITS, check_keys


def check_against_disciplines(cfg: dict, problem, discs) -> set[str]:
    """The problem against the run's disciplines: what they produce and consume; their parameters."""
    from bev_mdo.mdo.graph import CouplingGraph

    specs = [(d.name, tuple(d.inputs), tuple(d.outputs)) for d in discs]
    graph = CouplingGraph(specs)
    produced, consumed = set(graph.producer), {v for _, i, _ in specs for v in i}
    params = {p for d in discs for p in (getattr(d, "parameters", {}) or {})}
    for d in discs:  # a parameter comes from the config or the design, never from another discipline
        taken = sorted(set(getattr(d, "parameters", {}) or {}) & produced - set(d.inputs) - set(d.outputs))
        if taken:
            raise ValueError(f"discipline {graph.producer[taken[0]]!r} produces {taken[0]!r}, a parameter of discipline "
                             f"{d.name!r}, which would ignore it (a parameter is not a coupling variable): rename the "
                             "output, or give that discipline an input of this name")
    for name in [problem.objective] + [c.name for c in problem.constraints]:
        if name not in produced and f"{name}[0]" in produced:
            size = sum(1 for v in produced if v.startswith(f"{name}["))
            what = ("the objective must be a scalar; pick one element, e.g. " + f"{name}[0]"
                    if name == problem.objective else f"add shape: {size}")
            raise ValueError(f"problem: {name!r} is a vector of {size} elements (discipline "
                             f"{graph.producer[name + '[0]']!r}); {what}")
    if problem.objective not in produced:
        raise ValueError(f"problem.objective {problem.objective!r} is not produced by any discipline; "
                         + _outputs_hint(problem.objective, produced))
    for i, (name, _) in enumerate(problem.objectives):
        if name not in produced:
            raise ValueError(f"problem.objectives[{i}] {name!r} is not produced by any discipline; "
                             + _outputs_hint(name, produced))
    for c in problem.constraints:
        if c.name not in produced:
            raise ValueError(f"problem.constraints.{c.name}: no discipline produces it; " + _outputs_hint(c.name, produced))
        # an output whose values from a ceiling up stand for an infeasible design (not a measurement) takes
        # only upper limits below it, so that such a design is infeasible whatever the limit
        maker = next((d for d in discs if d.name == graph.producer[c.name]), None)
        ceiling = (getattr(maker, "upper_limit_below", None) or {}).get(c.name)
        if ceiling is not None and c.upper is not None and c.upper >= ceiling[0]:
            raise ValueError(f"problem.constraints.{c.name}.upper {c.upper:g}: must be below {ceiling[0]:g} "
                             f"({ceiling[1]})")
    if cfg["problem"]["battery_sized_for_range"] and SIZED_VARIABLE not in produced:
        raise ValueError("problem.battery_sized_for_range is true but no discipline produces battery_kwh "
                         "(add battery_sizing to disciplines:)")  # before its coupling guess, which it set
    for key, names in (("coupling_guesses", problem.coupling_guesses), ("coupling_bounds", problem.coupling_bounds)):
        for k in names:  # a name (or vector) no discipline produces would be ignored: a typo, said here
            if k not in produced and f"{k}[0]" not in produced:
                raise ValueError(f"problem.{key}.{k}: no discipline produces it; " + _outputs_hint(k, produced))
    for dv in problem.names:
        if dv in produced:
            hint = " (set problem.battery_sized_for_range: false, or drop the sizing discipline)" \
                if dv == SIZED_VARIABLE else ""
            raise ValueError(f"problem.design_variables.{dv}: it is also produced by discipline "
                             f"{graph.producer[dv]!r}{hint}")
        if dv not in consumed and dv not in params:
            raise ValueError(f"problem.design_variables.{dv}: no discipline consumes it; inputs: {sorted(consumed)}")
        builtin = [d.name for d in discs if dv in d.inputs and type(d).__module__.startswith("bev_mdo.disciplines")]
        if dv in DESIGN_LIMITS and builtin:  # the models refuse a point outside it: the optimiser's probes would fail
            lo, hi, unit = DESIGN_LIMITS[dv]
            where = f"[{lo:g}, {hi:g}]{' ' + unit if unit != '-' else ''}, where discipline {builtin[0]!r} accepts it"
            spec = next(d for d in problem.design_variables if d.name == dv)
            if spec.lower < lo or spec.upper > hi:
                raise ValueError(f"problem.design_variables.{dv}: bounds [{spec.lower:g}, {spec.upper:g}] reach "
                                 f"outside {where}")
            _check_battery_mass(dv, spec.upper, discs, problem)
    # a baseline the models refuse would be shown as a column of NaN beside the result
    check_model_limits(discs, ((cfg["problem"].get("baseline") or {}).get("design") or {}), "problem.baseline.design.")
    check_model_limits(discs, problem.parameters, "problem.parameters.")
    for k in problem.parameters:
        if k in produced:  # the flow takes a produced variable from its producer: the value would be ignored
            raise ValueError(f"problem.parameters.{k}: it is produced by discipline {graph.producer[k]!r}, "
                             "which a fixed value cannot replace (drop that discipline, or write your own without it)")
        if k not in params and k not in consumed:
            raise ValueError(f"problem.parameters.{k}: no discipline has this parameter; known: {sorted(params)}")
    check_optimizer_variables(cfg["optimizer"]["name"], problem.names, [c for c in graph.couplings if c not in problem.names]
                              if cfg["formulation"] == "idf" else [], problem.coupling_bound)
    graph.check_inputs(set(problem.names) | set(problem.parameters))
    return params


def _check_battery_mass(dv: str, upper: float, discs, problem) -> None:
    """A battery_kwh bound whose battery alone outweighs the heaviest vehicle the models accept (a pack typed
    in Wh): every design near it failed, each naming only the vehicle's mass. battery_kg_per_kwh as the run
    takes it: a problem parameter, the lower bound of a design variable, else the vehicle's."""
    mass = next((d for d in discs if dv == "battery_kwh" and dv in d.inputs
                 and "battery_kg_per_kwh" in (getattr(d, "parameters", None) or {})), None)
    if mass is None:
        return
    lightest = {d.name: d.lower for d in problem.design_variables}.get("battery_kg_per_kwh")
    kg_per_kwh = float(problem.parameters.get("battery_kg_per_kwh", lightest if lightest is not None
                                              else mass.parameters["battery_kg_per_kwh"]))
    heaviest = DESIGN_LIMITS["vehicle_mass_kg"][1]
    if upper * kg_per_kwh > heaviest:
        raise ValueError(f"problem.design_variables.battery_kwh: upper bound {upper:g} kWh is {upper * kg_per_kwh:,.0f} kg "
                         f"of battery at battery_kg_per_kwh {kg_per_kwh:g}, above the {heaviest:,.0f} kg vehicle "
                         f"discipline {mass.name!r} accepts (a pack in Wh?)")


def check_optimizer_variables(optimizer: str, design: list[str], couplings: list[str], coupling_bound) -> None:
    """What an optimiser needs of its variables (the design variables, and IDF's ``couplings``), checked at
    load rather than when it starts: finite bounds for one that samples the whole box, two variables for
    ``chebyshev-pairwise``, which moves them in pairs."""
    from bev_mdo.mdo.optimizers import FINITE_BOUNDS

    open_ = [c for c in couplings if not all(math.isfinite(b) for b in coupling_bound(c))]
    if optimizer in FINITE_BOUNDS and open_:
        raise ValueError(f"optimizer {optimizer} needs finite bounds on every optimiser variable: with formulation "
                         f"idf give problem.coupling_bounds for {open_}")
    if optimizer == "chebyshev-pairwise" and len(design) + len(couplings) < 2:
        raise ValueError(f"optimizer chebyshev-pairwise needs at least 2 optimiser variables (it moves them in "
                         f"pairs); the problem has {design + couplings}")


def model_limits(discs, name: str) -> tuple[float, float, str, bool, str] | None:
    """(lower, upper, unit, integer, discipline): the range in which the run's built-in disciplines accept
    a value of ``name`` (a design variable's physical design limit, ``DESIGN_LIMITS``, or a model
    parameter's range, ``models.params``) and the first built-in discipline that reads it; None when no
    built-in discipline reads it or no range is declared (a discipline of yours checks its own)."""
    from bev_mdo.models.params import all_specs

    builtin = [d for d in discs if type(d).__module__.startswith("bev_mdo.disciplines")]
    reader = next((d.name for d in builtin if name in d.inputs), None)
    if name in DESIGN_LIMITS and reader:
        return (*DESIGN_LIMITS[name], False, reader)
    spec = all_specs().get(name)
    reader = next((d.name for d in builtin if name in (getattr(d, "parameters", {}) or {})), None)
    if spec is not None and reader:
        return spec.lower, spec.upper, spec.unit, spec.integer, reader
    return None


def check_model_limits(discs, values: Mapping[str, Any], where: str = "") -> None:
    """ValueError for the first value (a number or an array of them) of a design variable or parameter that
    the run's built-in disciplines refuse (:func:`model_limits`): a design they can never evaluate. A value
    outside a design variable's bounds but inside its physical limit is not checked here. ``where``: the
    key path of ``values`` (``problem.parameters.``)."""
    import numpy as np

    for name, value in values.items():
        limits = model_limits(discs, name)
        if limits is None or isinstance(value, (bool, str)):  # not a number: refused where it is read
            continue
        lo, hi, unit, integer, reader = limits
        a = np.atleast_1d(np.asarray(value, dtype=float)).reshape(-1)
        outside = a[~((a >= lo) & (a <= hi))]
        unit = f" {unit}" if unit and unit != "-" else ""
        if outside.size:
            raise ValueError(f"{where}{name}: {outside[0]:g} is outside [{lo:g}, {hi:g}]{unit}, where discipline "
                             f"{reader!r} accepts it")
        fractional = a[a != np.round(a)] if integer else a[:0]
        if fractional.size:
            raise ValueError(f"{where}{name}: {fractional[0]:g} is not a whole number, which discipline {reader!r} "
                             "needs")


def resolve_disciplines(config: Mapping[str, Any]) -> list:
    """Discipline objects of a run: the config's ``disciplines`` list, else the built-in defaults.

    A list entry is a built-in name, or ``{name, class: "module:Class", options: {...}}``;
    ``{name}`` without ``class`` picks the built-in of that name.
    """
    from bev_mdo.disciplines import BUILTIN, default_disciplines

    entries = config.get("disciplines")
    if entries is None:
        out = [wrap(d) for d in default_disciplines(config)]
        return attach_units(out, [d.name for d in out])
    if not isinstance(entries, list) or not entries:
        raise ValueError("disciplines must be a non-empty list of names or {name, class, options} entries")
    out = []
    for k, e in enumerate(entries):
        if isinstance(e, str):
            e = {"name": e}
        if not isinstance(e, Mapping) or not isinstance(e.get("name"), str):
            raise ValueError(f"disciplines[{k}] must be a name or a mapping with a 'name'")
        check_keys(f"disciplines[{k}] ({e['name']})", e, ("name", "class", "options"))
        options = e.get("options") or {}
        if not isinstance(options, Mapping):
            raise ValueError(f"disciplines[{k}] ({e['name']}): options must be a mapping")
        if "class" not in e:
            if e["name"] not in BUILTIN:
                raise ValueError(f"disciplines[{k}]: no built-in discipline {e['name']!r}; built-ins: "
                                 f"{sorted(BUILTIN)} (or give class: 'module:Class')")
            cls = BUILTIN[e["name"]]
        else:
            try:
                cls = load_class(str(e["class"]), config.get("search_path") or ())
            except ValueError as exc:
                raise ValueError(f"disciplines[{k}] ({e['name']}): {exc}") from None
        options = read_options(cls, options, f"disciplines[{k}] ({e['name']}).options")
        try:
            if hasattr(cls, "from_config"):
                disc = cls.from_config(config, options)
            else:
                disc = cls(**options_dict(options))
        except Exception as exc:  # the user's constructor: one line naming the discipline, never a traceback
            raise ValueError(f"disciplines[{k}] ({e['name']}): cannot build {getattr(cls, '__name__', cls)}: "
                             f"{type(exc).__name__}: {exc}") from None
        for attr in ("inputs", "outputs", "compute"):
            if not hasattr(disc, attr):
                raise ValueError(f"disciplines[{k}] ({e['name']}): {cls.__name__} has no {attr!r}")
        for attr in ("inputs", "outputs"):
            names = getattr(disc, attr)
            if isinstance(names, str) or not all(isinstance(v, str) and v for v in names):
                raise ValueError(f"disciplines[{k}] ({e['name']}): {attr} must be a sequence of variable names, "
                                 f"got {names!r}")
            twice = sorted({v for v in names if list(names).count(v) > 1})
            if twice:
                raise ValueError(f"disciplines[{k}] ({e['name']}): {attr} name {twice} twice")
        both = sorted(set(disc.inputs) & set(disc.outputs))
        if both:
            raise ValueError(f"disciplines[{k}] ({e['name']}): {both} are both inputs and outputs")
        if getattr(disc, "name", None) != e["name"]:
            try:
                disc.name = e["name"]
            except AttributeError:
                raise ValueError(f"disciplines[{k}]: {cls.__name__} is named {disc.name!r}, not {e['name']!r}") from None
        out.append(wrap(disc))
    return attach_units(out, [f"disciplines[{k}] ({d.name})" for k, d in enumerate(out)])


def discipline_entries(config: Mapping[str, Any], discs=None) -> list[dict]:
    """``{name, class, options}`` for every discipline of a run (what a node needs to build one);
    ``discs``: the run's disciplines already built (``RunConfig.disciplines``)."""
    out = []
    for d in resolve_disciplines(config) if discs is None else discs:
        cls = type(getattr(d, "inner", d))
        out.append({"name": d.name, "class": f"{cls.__module__}:{cls.__qualname__}", "options": {}})
    if config.get("disciplines") is not None:
        user = {(e if isinstance(e, str) else e["name"]): e for e in config["disciplines"]}
        for o in out:
            e = user.get(o["name"])
            if isinstance(e, Mapping):
                o["options"] = dict(e.get("options") or {})
                if e.get("class"):
                    o["class"] = str(e["class"])  # as the user wrote it (resolved through search_path)
    return out


def discipline_names(config: Mapping[str, Any]) -> list[str]:
    """Names of a run's disciplines, read from the config without building any discipline."""
    entries = config.get("disciplines")
    if entries is None:
        from bev_mdo.disciplines import default_names

        return default_names(config)
    return [e if isinstance(e, str) else e["name"] for e in entries]


def _outputs_hint(name: str, produced) -> str:
    """``did you mean 'range_km'? outputs: [...]`` (the nearest output by difflib, as --constraint says)."""
    from bev_mdo.mdo.vectors import did_you_mean

    return did_you_mean(name, produced) + f"outputs: {sorted(produced)}"
