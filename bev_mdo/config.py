"""Run-config loading: read the YAML, validate every section, resolve the disciplines.

``load_config(path)`` returns a resolved dict; any problem raises a one-line
ValueError naming the file and the key. In battery-sized-for-range mode
``battery_kwh`` leaves the design variables (its initial value becomes the MDA
loop's starting guess), is produced by the ``battery_sizing`` discipline, and the
``range_km`` constraint (met by construction) becomes ``monitor: true``.
"""
from __future__ import annotations

import copy
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bev_mdo.mdo.settings import MDASettings, OptimizerSettings, RunSettings
from bev_mdo.models.common import check_keys

TOP_KEYS = ("name", "description", "vehicle", "cycle", "energy_model", "disciplines", "problem",
            "formulation", "mda", "optimizer", "ros", "recording", "search_path", "cycle_traces")
FORMULATIONS = ("mdf", "idf")
RECORDING_KEYS = ()  # nothing reads a key of the recording section yet: any key there would do nothing
# the engine sections' defaults, defined once with their types (mdo/settings.py)
MDA_DEFAULTS = MDASettings().as_dict()
OPTIMIZER_DEFAULTS = OptimizerSettings().as_dict()
SIZED_VARIABLE = "battery_kwh"
SIZED_CONSTRAINT = "range_km"


def load_config(path: str | Path | Mapping[str, Any], edit=None) -> dict:
    """Read and validate a run config (a YAML path, or an already-parsed mapping).

    ``search_path`` (where a discipline's ``module:Class`` is looked for, before Python's own path)
    becomes absolute: the config's own entries (relative ones against its folder), then the config
    file's folder, then the working directory. A resolved config written elsewhere (a run's log
    folder, a bag) keeps them, so every process of a run resolves user modules the same way.
    ``edit(raw) -> raw`` changes the parsed mapping before it is checked (command-line overrides).
    """
    base: Path | None = None
    if isinstance(path, Mapping):
        where, raw = "<config>", copy.deepcopy(dict(path))
    else:
        from bev_mdo.yamlload import read_yaml_file

        p = Path(path)
        where = str(p)
        if not p.is_file():
            raise ValueError(f"{where}: no such config file")
        raw = read_yaml_file(p)  # one-line ValueErrors: binary, too big, too deep, alias bomb, bad YAML
        base = p.resolve().parent
    if edit is not None and isinstance(raw, Mapping):
        raw = edit(raw)
    try:
        if isinstance(raw, Mapping):
            raw = {**raw, "search_path": _search_path(raw.get("search_path"), base)}
        return _resolve(raw)
    except ValueError as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else "invalid config"
        raise ValueError(f"{where}: {msg}") from None


def check_run_name(name: Any) -> None:
    """A run's ``name`` becomes part of its bag and log folder names: ValueError unless it is a plain
    name (no path separator, not '.' or '..', no control character, at most 100 characters)."""
    bad = (not isinstance(name, str) or not name.strip() or "/" in name or "\\" in name or name in (".", "..")
           or ".." in name or len(name) > 100 or any(ord(c) < 32 for c in name))
    if bad:
        raise ValueError(f"name {name!r} must be a plain run name (letters, digits, '-', '_', '.'; no path "
                         "separator, no '..', at most 100 characters): it names the run's bag and log folders")


def load_yaml(text: str) -> Any:
    """Parse YAML like yaml.safe_load, but a key given twice in one mapping is an error and the size,
    nesting, aliases and list lengths are limited (bev_mdo.yamlload)."""
    from bev_mdo.yamlload import load_yaml as load

    return load(text)


# scipy solver behind each built-in optimiser: its keyword arguments are the accepted options
_SCIPY_SOLVERS = {"SLSQP": ("scipy.optimize._minimize", "_minimize_slsqp"),
                  "trust-constr": ("scipy.optimize._minimize", "_minimize_trustregion_constr"),
                  "COBYLA": ("scipy.optimize._minimize", "_minimize_cobyla"),
                  "COBYQA": ("scipy.optimize._minimize", "_minimize_cobyqa"),
                  "differential_evolution": ("scipy.optimize", "differential_evolution")}
_NOT_OPTIONS = {"fun", "func", "x0", "args", "jac", "hess", "hessp", "bounds", "constraints", "callback"}


def check_optimizer_options(name: str, options: Mapping[str, Any]) -> None:
    """ValueError naming the first key of `options` that the optimiser does not accept, with the
    nearest one: the keyword arguments of its scipy solver (scipy itself only warns, after the nodes
    have started), or the ``DEFAULTS`` of a plug-in module (``chebyshev-pairwise``)."""
    import importlib
    import inspect

    from bev_mdo.mdo.optimizers import OPTIMIZERS

    where = _SCIPY_SOLVERS.get(name)
    plugin = OPTIMIZERS.get(name)
    if where is None and isinstance(plugin, str):
        try:
            defaults = getattr(importlib.import_module(plugin.partition(":")[0]), "DEFAULTS", None)
        except ImportError:
            defaults = None
        if isinstance(defaults, Mapping):
            check_keys("optimizer.options", options, defaults, of=name)
        return
    if where is None:
        return
    try:
        fn = getattr(importlib.import_module(where[0]), where[1])
        params = inspect.signature(fn).parameters
    except (ImportError, AttributeError, ValueError, TypeError):
        return
    known = [k for k, p in params.items() if k not in _NOT_OPTIONS and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]
    check_keys("optimizer.options", options, known, of=name)
    for key, value in options.items():
        default = params[key].default
        if (isinstance(default, (int, float)) and not isinstance(default, bool)
                and (isinstance(value, bool) or not isinstance(value, (int, float)))):
            raise ValueError(f"optimizer.options.{key}: {value!r} is not a number ({name}'s default is {default!r})")


def _resolve(raw: Any) -> dict:
    from bev_mdo.mdo.formulations import FD_SCHEMES
    from bev_mdo.mdo.mda import METHODS
    from bev_mdo.mdo.optimizers import canonical_name
    from bev_mdo.mdo.problem import Problem

    if not isinstance(raw, Mapping):
        raise ValueError("the config must be a YAML mapping of sections (name, vehicle, cycle, problem, ...)")
    check_keys("", raw, TOP_KEYS)
    cfg = dict(raw)
    cfg.setdefault("name", "run")
    check_run_name(cfg["name"])
    cfg["energy_model"] = cfg.get("energy_model", "flat")
    from bev_mdo.disciplines import ENERGY_MODELS

    if cfg["energy_model"] not in ENERGY_MODELS:
        raise ValueError(f"energy_model {cfg['energy_model']!r} is unknown; allowed: {', '.join(ENERGY_MODELS)}")
    _validate_models(cfg)
    _vehicle_topology_into_options(cfg)
    cfg["formulation"] = str(cfg.get("formulation", "mdf")).lower()
    if cfg["formulation"] not in FORMULATIONS:
        raise ValueError(f"formulation {raw.get('formulation')!r} is unknown; allowed: {', '.join(FORMULATIONS)}")
    cfg["mda"] = _section(cfg.get("mda"), MDA_DEFAULTS, "mda")
    if cfg["mda"]["method"] not in METHODS:
        raise ValueError(f"mda.method {cfg['mda']['method']!r} is unknown; allowed: {', '.join(METHODS)}")
    cfg["optimizer"] = _section(cfg.get("optimizer"), OPTIMIZER_DEFAULTS, "optimizer")
    cfg["optimizer"]["name"] = canonical_name(cfg["optimizer"]["name"])
    if not isinstance(cfg["optimizer"]["options"], Mapping):
        raise ValueError("optimizer.options must be a mapping of the optimiser's own options")
    check_optimizer_options(cfg["optimizer"]["name"], cfg["optimizer"]["options"])
    if cfg["optimizer"]["fd_scheme"] not in FD_SCHEMES:
        raise ValueError(f"optimizer.fd_scheme {cfg['optimizer']['fd_scheme']!r} is unknown; allowed: "
                         f"{', '.join(FD_SCHEMES)}")
    tol = cfg["optimizer"]["feasibility_tolerance"]
    if isinstance(tol, bool) or not isinstance(tol, (int, float)) or not 0 <= tol < 1 or math.isnan(tol):
        raise ValueError(f"optimizer.feasibility_tolerance {tol!r} must be a number in [0, 1) "
                         "(on normalised constraints; default 1e-4)")
    cfg["optimizer"]["feasibility_tolerance"] = float(tol)
    from bev_mdo.mdo.formulations import DERIVATIVES

    if cfg["optimizer"]["derivatives"] not in DERIVATIVES:
        raise ValueError(f"optimizer.derivatives {cfg['optimizer']['derivatives']!r} is unknown; allowed: "
                         f"{', '.join(DERIVATIVES)}")
    for key in ("ros", "recording"):
        if cfg.get(key) is not None and not isinstance(cfg[key], Mapping):
            raise ValueError(f"{key} must be a mapping")
        cfg[key] = dict(cfg.get(key) or {})
    check_keys("recording", cfg["recording"], RECORDING_KEYS)
    from bev_mdo.ros_settings import validate_ros

    validate_ros(cfg["ros"])  # checked here so the error names the file; the section is kept as written
    cfg["problem"] = _resolve_problem(cfg.get("problem"))
    problem = Problem.from_config(cfg["problem"])
    # numeric checks of the engine sections, by constructing the pieces once
    _check_mda_numbers(cfg["mda"])
    params = _check_against_disciplines(cfg, problem)
    _check_baseline(cfg, problem, params)
    return cfg


def _search_path(given: Any, base: Path | None) -> list[str]:
    """Absolute folders for user modules: the given ones, the config's folder, the working directory."""
    if given is None:
        given = []
    if isinstance(given, str) or not isinstance(given, list) or not all(isinstance(d, str) for d in given):
        raise ValueError("search_path must be a list of folders (relative ones count from the config's folder)")
    out: list[str] = []
    for d in [*given, *([str(base)] if base else []), os.getcwd()]:
        p = Path(d).expanduser()
        p = p if p.is_absolute() or base is None else base / p
        s = str(p.resolve())
        if s not in out:
            out.append(s)
    return out


def _section(value: Any, defaults: Mapping[str, Any], where: str) -> dict:
    if value is None:
        value = {}
    if isinstance(value, str) and where == "optimizer":
        value = {"name": value}
    if not isinstance(value, Mapping):
        raise ValueError(f"{where} must be a mapping with keys {sorted(defaults)}")
    check_keys(where, value, defaults)
    return {**copy.deepcopy(dict(defaults)), **dict(value)}


def _check_mda_numbers(mda: Mapping[str, Any]) -> None:
    tol, it, w = mda["tolerance"], mda["max_iterations"], mda["relaxation"]
    if not isinstance(tol, (int, float)) or not tol > 0:
        raise ValueError(f"mda.tolerance {tol!r} must be a number > 0")
    if isinstance(it, bool) or not isinstance(it, int) or it < 1:
        raise ValueError(f"mda.max_iterations {it!r} must be an integer >= 1")
    if not isinstance(w, (int, float)) or not 0 < w <= 2:
        raise ValueError(f"mda.relaxation {w!r} must be in (0, 2]")
    if not isinstance(mda["warm_start"], bool) and mda["warm_start"] not in ("auto", "tangent"):
        raise ValueError(f"mda.warm_start {mda['warm_start']!r} must be true, false, auto or tangent")
    if mda["warm_start"] == "tangent" and mda["method"] != "newton":
        raise ValueError(f"mda.warm_start tangent needs mda.method newton, not {mda['method']}")
    if not isinstance(mda["fuse_downstream"], bool):
        raise ValueError(f"mda.fuse_downstream {mda['fuse_downstream']!r} must be true or false")


def _inline_parameter_set_file(cfg: dict) -> None:
    """A parameter set named by its file (``vehicle.parameter_set: mine.yaml``) is read once, here, and
    its values go into the vehicle section as defaults (keys given there still win), so the resolved
    config reproduces the run alone: a bag's ``resume``, a node started in another folder or on another
    host, the same run after the file moved or was rewritten. A shipped set stays named (it comes with
    the package, whose version the bag records)."""
    from bev_mdo.models import params

    v = cfg.get("vehicle")
    name = v.get("parameter_set") if isinstance(v, Mapping) else None
    if not params.is_parameter_set_file(name):
        return
    values = params.load_parameter_set(name)
    replaced = params.ROAD_LOAD_REPLACES if "road_load" in v or any(
        k.startswith("road_load_") for k in v) else ()  # unused beside a road load, and refused there
    section = {k: x for k, x in v.items() if k != "parameter_set"}
    cfg["vehicle"] = {**{k: x for k, x in values.items() if k not in section and k not in replaced}, **section}


def _record_cycle_traces(cfg: dict) -> None:
    """Every drive-cycle CSV the run names (``cycle.name``, the energy and cycle_range options ``cycle``
    and ``cycle_weights``) is read once, here, into the resolved config's ``cycle_traces`` (path ->
    {time_s, speed_m_s}); the models take it from there, so a bag's ``resume`` and nodes started in
    another folder or on another host run on the same trace without the file. A trace already there
    (a resolved config read again) is checked, not re-read."""
    import warnings

    from bev_mdo.models.cycles import CycleNote, is_csv_cycle, load_cycle, trace_cycle, trace_record, unbalanced_note

    traces = cfg.get("cycle_traces") or {}
    if not isinstance(traces, Mapping):
        raise ValueError("cycle_traces must map CSV paths to {time_s: [...], speed_m_s: [...]}")
    names = [cfg["cycle"]["name"]]
    for e in cfg.get("disciplines") or []:
        if isinstance(e, Mapping) and e.get("name") in ("energy", "cycle_range") and not e.get("class"):
            opts = e.get("options") or {}
            if isinstance(opts.get("cycle"), str):
                names.append(opts["cycle"])
            if isinstance(opts.get("cycle_weights"), Mapping):
                names += [str(k) for k in opts["cycle_weights"]]
    out = {}
    for name in dict.fromkeys(n for n in names if is_csv_cycle(n)):
        if name in traces:  # a resolved config read again: check what it holds
            cycle, out[name] = trace_cycle(name, traces[name]), traces[name]
        else:  # read (and checked) from the file
            cycle = load_cycle(name)
            out[name] = trace_record(cycle)
        note = unbalanced_note(cycle, name)
        if note:
            warnings.warn(note, CycleNote, stacklevel=2)
    if out:
        cfg["cycle_traces"] = out
    else:
        cfg.pop("cycle_traces", None)


def _validate_models(cfg: dict) -> None:
    """Vehicle and cycle sections are checked by the models' own validators."""
    from bev_mdo.models import params

    if "vehicle" in cfg or "cycle" in cfg:
        try:
            _inline_parameter_set_file(cfg)
            params.validate_vehicle(cfg.get("vehicle"))
        except ValueError as exc:  # a key path (vehicle.x) says where already
            raise ValueError(str(exc) if str(exc).startswith("vehicle.") else f"vehicle: {exc}") from None
        try:
            cfg["cycle"] = params.validate_cycle(cfg.get("cycle"))
            from bev_mdo.models.cycles import load_cycle, resample

            _record_cycle_traces(cfg)
            c = cfg["cycle"]  # read and check the trace now: one line naming file and row
            resample(load_cycle(c["name"], cfg.get("cycle_traces")), c["dt_s"], c["interpolation"], c["smoothing"])
        except ValueError as exc:
            raise ValueError(str(exc) if str(exc).startswith("cycle.") else f"cycle: {exc}") from None


def _vehicle_topology_into_options(cfg: dict) -> None:
    """``vehicle.topology`` also becomes the ``topology`` option of every listed built-in topology
    discipline that does not set one, so the resolved config says it where a discipline node
    reads it (a node keeps only the numeric vehicle parameters)."""
    t, entries = (cfg.get("vehicle") or {}).get("topology"), cfg.get("disciplines")
    if t is None or not isinstance(entries, list):
        return
    from bev_mdo.disciplines import TOPOLOGY_DISCIPLINES

    out = []
    for e in entries:
        if isinstance(e, str) and e in TOPOLOGY_DISCIPLINES:
            e = {"name": e, "options": {"topology": t}}
        elif (isinstance(e, Mapping) and e.get("name") in TOPOLOGY_DISCIPLINES and "class" not in e
              and isinstance(e.get("options") or {}, Mapping)):
            e = {**e, "options": {"topology": t, **(e.get("options") or {})}}
        out.append(e)
    cfg["disciplines"] = out


def _resolve_problem(section: Any) -> dict:
    if not isinstance(section, Mapping):
        raise ValueError("problem must be a mapping with objective, design_variables and constraints")
    prob = copy.deepcopy(dict(section))
    sized = prob.get("battery_sized_for_range", False)
    if not isinstance(sized, bool):
        raise ValueError(f"problem.battery_sized_for_range {sized!r} must be true or false")
    prob["battery_sized_for_range"] = sized
    dvs = prob.get("design_variables")
    if sized and isinstance(dvs, Mapping) and SIZED_VARIABLE in dvs:
        dvs = dict(dvs)
        spec = dvs.pop(SIZED_VARIABLE)
        prob["design_variables"] = dvs
        if isinstance(spec, Mapping) and "initial" in spec:
            prob.setdefault("coupling_guesses", {}).setdefault(SIZED_VARIABLE, spec["initial"])
    base = prob.get("baseline")
    if base is not None:
        if not isinstance(base, Mapping) or set(base) - {"name", "design"} or not isinstance(base.get("design"), Mapping):
            raise ValueError("problem.baseline must be {name: <label>, design: {<design variable>: <value>, ...}}")
        label = base.get("name", "baseline")
        if not isinstance(label, str) or not label.strip():
            raise ValueError("problem.baseline.name must be a non-empty label, e.g. 'Nissan Leaf'")
        design = {}
        for k, v in base["design"].items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise ValueError(f"problem.baseline.design.{k}: {v!r} must be a finite number")
            if not (sized and k == SIZED_VARIABLE):  # sized mode: the battery is sized, not given
                design[str(k)] = float(v)
        prob["baseline"] = {"name": label.strip(), "design": design}
    cons = prob.get("constraints")
    if sized and isinstance(cons, Mapping) and isinstance(cons.get(SIZED_CONSTRAINT), Mapping):
        # battery_sizing meets the range target exactly; as an optimiser constraint it would duplicate
        # the consistency equality (rank-deficient in IDF), so it is only monitored
        prob["constraints"] = {**cons, SIZED_CONSTRAINT: {**cons[SIZED_CONSTRAINT], "monitor": True}}
    return prob


def _check_baseline(cfg: dict, problem, params: set[str]) -> None:
    base = cfg["problem"].get("baseline")
    if base is None:
        return
    design = base["design"]
    missing = [n for n in problem.names if n not in design]
    if missing:
        raise ValueError(f"problem.baseline.design misses design variables {missing}; give every one of {problem.names}")
    unknown = [k for k in design if k not in problem.names and k not in params]
    if unknown:
        raise ValueError(f"problem.baseline.design.{unknown[0]}: neither a design variable {problem.names} "
                         "nor a discipline parameter")


def _check_against_disciplines(cfg: dict, problem) -> set[str]:
    from bev_mdo.mdo.graph import CouplingGraph

    discs = resolve_disciplines(cfg)
    specs = [(d.name, tuple(d.inputs), tuple(d.outputs)) for d in discs]
    graph = CouplingGraph(specs)
    produced, consumed = set(graph.producer), {v for _, i, _ in specs for v in i}
    params = {p for d in discs for p in (getattr(d, "parameters", {}) or {})}
    if problem.objective not in produced or any(c.name not in produced for c in problem.constraints):
        for name in [problem.objective] + [c.name for c in problem.constraints]:
            if name not in produced and f"{name}[0]" in produced:
                size = sum(1 for v in produced if v.startswith(f"{name}["))
                what = ("the objective must be a scalar; pick one element, e.g. " + f"{name}[0]"
                        if name == problem.objective else f"add shape: {size}")
                raise ValueError(f"problem: {name!r} is a vector of {size} elements (discipline "
                                 f"{graph.producer[name + '[0]']!r}); {what}")
    if problem.objective not in produced:
        raise ValueError(f"problem.objective {problem.objective!r} is not produced by any discipline; "
                         f"outputs: {sorted(produced)}")
    for i, (name, _) in enumerate(problem.objectives):
        if name not in produced:
            raise ValueError(f"problem.objectives[{i}] {name!r} is not produced by any discipline; "
                             f"outputs: {sorted(produced)}")
    for c in problem.constraints:
        if c.name not in produced:
            raise ValueError(f"problem.constraints.{c.name}: no discipline produces it; outputs: {sorted(produced)}")
    for key, names in (("coupling_guesses", problem.coupling_guesses), ("coupling_bounds", problem.coupling_bounds)):
        for k in names:  # a name (or vector) no discipline produces would be ignored: a typo, said here
            if k not in produced and f"{k}[0]" not in produced:
                raise ValueError(f"problem.{key}.{k}: no discipline produces it; outputs: {sorted(produced)}")
    for dv in problem.names:
        if dv in produced:
            hint = " (set problem.battery_sized_for_range: false, or drop the sizing discipline)" \
                if dv == SIZED_VARIABLE else ""
            raise ValueError(f"problem.design_variables.{dv}: it is also produced by discipline "
                             f"{graph.producer[dv]!r}{hint}")
        if dv not in consumed and dv not in params:
            raise ValueError(f"problem.design_variables.{dv}: no discipline consumes it; inputs: {sorted(consumed)}")
    for k in problem.parameters:
        if k not in params and k not in consumed:
            raise ValueError(f"problem.parameters.{k}: no discipline has this parameter; known: {sorted(params)}")
    if cfg["problem"]["battery_sized_for_range"] and SIZED_VARIABLE not in produced:
        raise ValueError("problem.battery_sized_for_range is true but no discipline produces battery_kwh "
                         "(add the battery_sizing discipline)")
    graph.check_inputs(set(problem.names) | set(problem.parameters))
    return params


def resolve_disciplines(config: Mapping[str, Any]) -> list:
    """Discipline objects of a run: the config's ``disciplines`` list, else the built-in defaults.

    A list entry is a built-in name, or ``{name, class: "module:Class", options: {...}}``;
    ``{name}`` without ``class`` picks the built-in of that name.
    """
    from bev_mdo.mdo.discipline import load_class, options_dict, read_options
    from bev_mdo.mdo.units import attach_units
    from bev_mdo.mdo.vectors import wrap

    entries = config.get("disciplines")
    if entries is None:
        out = [wrap(d) for d in _defaults(config)]
        return attach_units(out, [d.name for d in out])
    if not isinstance(entries, list) or not entries:
        raise ValueError("disciplines must be a non-empty list of names or {name, class, options} entries")
    out, builtins = [], None
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
            builtins = builtins if builtins is not None else _builtins()
            if e["name"] not in builtins:
                raise ValueError(f"disciplines[{k}]: no built-in discipline {e['name']!r}; built-ins: "
                                 f"{sorted(builtins)} (or give class: 'module:Class')")
            cls = builtins[e["name"]]
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


def _builtins() -> dict[str, type]:
    from bev_mdo.disciplines import BUILTIN

    return dict(BUILTIN)


def _defaults(config: Mapping[str, Any]) -> list:
    from bev_mdo.disciplines import default_disciplines

    return list(default_disciplines(config))


def discipline_entries(config: Mapping[str, Any]) -> list[dict]:
    """``{name, class, options}`` for every discipline of a run (what a node needs to build one)."""
    out = []
    for d in resolve_disciplines(config):
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


def run_settings(config: Mapping[str, Any]) -> RunSettings:
    """The engine's typed settings of a resolved config (``load_config``'s result), built once and
    passed down: problem, formulation, the ``mda:``/``optimizer:`` sections, the disciplines by name
    and whether each provides analytic partials (the driver imports nothing above the engine)."""
    from bev_mdo.mdo.vectors import has_partials

    names = tuple(discipline_names(config))
    partials = {d.name: bool(has_partials(d)) for d in resolve_disciplines(config)}
    return RunSettings(config["problem"], str(config["formulation"]), MDASettings.of(config["mda"]),
                       OptimizerSettings.of(config["optimizer"]), names,
                       {n: partials.get(n, False) for n in names})


def plain(obj):
    """YAML-safe copy of a config (numpy scalars to floats, tuples to lists)."""
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if hasattr(obj, "item"):
        return obj.item()
    return obj
