"""Checks of a run config's sections, one at a time (``load._resolve`` runs them in order); a
parameter-set file and drive-cycle CSVs are read once, into the resolved config. Every problem is a
one-line ValueError naming the key.
"""
from __future__ import annotations

import copy
import importlib
import inspect
import math
import os
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from bev_mdo.models import params
from bev_mdo.models.common import check_keys, is_number, text_hint
from bev_mdo.models.cycles import (CycleNote, is_csv_cycle, load_cycle, trace_cycle, trace_record, trace_yaml_chars,
                                   unbalanced_note)

SIZED_VARIABLE = "battery_kwh"
SIZED_CONSTRAINT = "range_km"


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
    have started), or the ``DEFAULTS`` of a plug-in module (``chebyshev-pairwise``) and its
    ``check_options`` of the values."""
    from bev_mdo.mdo.optimizers import COUNT_OPTIONS, OPTIMIZERS

    _check_solver_options(name, options, OPTIMIZERS.get(name))
    if name not in OPTIMIZERS:
        return
    for key in COUNT_OPTIONS & set(options):
        value = options[key]
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ValueError(f"optimizer.options.{key}: {value!r} must be a whole number of at least 1{text_hint(value)}")


def _check_solver_options(name: str, options: Mapping[str, Any], plugin) -> None:
    """The keys of `options` against the solver's own, and a number where its default is one."""
    where = _SCIPY_SOLVERS.get(name)
    if where is None and isinstance(plugin, str):
        try:
            module = importlib.import_module(plugin.partition(":")[0])
        except ImportError:
            return
        defaults = getattr(module, "DEFAULTS", None)
        if isinstance(defaults, Mapping):
            check_keys("optimizer.options", options, defaults, of=name)
        if callable(getattr(module, "check_options", None)):  # the values, as the plug-in would take them
            module.check_options(options)
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
        if is_number(default) and not is_number(value):
            raise ValueError(f"optimizer.options.{key}: {value!r} is not a number ({name}'s default is {default!r})"
                             f"{text_hint(value)}")
        # scipy takes nan and inf (and a negative tolerance) and runs on: ftol .nan ended at once as a
        # success, .inf or -1 as "no progress"; an infinite value is kept only where the default is one
        if is_number(value) and (math.isnan(value) or math.isinf(value) and not (
                is_number(default) and math.isinf(default))):
            raise ValueError(f"optimizer.options.{key}: {value!r} must be a finite number")
        if "tol" in key and is_number(value) and value < 0:
            raise ValueError(f"optimizer.options.{key}: {value!r} is a tolerance, it must be >= 0")


def search_path(given: Any, base: Path | None) -> list[str]:
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


def note_missing_folders(folders: Any) -> None:
    """A note (``CycleNote``, one line) per ``search_path`` folder that does not exist, once the run's classes
    were found without it (a class not found names it in load_class's error): a typo in the config, most likely."""
    for d in folders if isinstance(folders, list) else ():
        if not Path(d).is_dir():
            warnings.warn(f"search_path: {d} {'is not a folder' if Path(d).exists() else 'does not exist'}",
                          CycleNote, stacklevel=2)


def anchor_paths(raw: Mapping[str, Any], base: Path) -> dict:
    """A config file's relative paths made absolute against its folder ``base``, as its reader expects
    wherever the command runs: drive-cycle CSVs (``cycle.name``, the energy and cycle_range options
    ``cycle`` and ``cycle_weights``), ``vehicle.parameter_set`` (a .yaml of yours), ``ros.sign_key_file``
    and ``search_path``. A name ``cycle_traces`` holds stays as it is (a resolved config read again);
    a config given as a mapping is not anchored (its paths count from the working directory)."""
    cfg = copy.deepcopy(dict(raw))
    traces = cfg.get("cycle_traces") if isinstance(cfg.get("cycle_traces"), Mapping) else {}

    def at(name: Any, file_like=lambda p: True) -> Any:
        if not isinstance(name, str) or not name.strip() or name in traces:
            return name
        p = Path(name.strip()).expanduser()
        return name if p.is_absolute() or not file_like(p) else str(base / p)

    def cycle(name: Any) -> Any:  # a built-in cycle's name, or a word that is no file there, stays
        return at(name, lambda p: is_csv_cycle(str(p)) and (p.suffix.lower() == ".csv" or (base / p).exists()))

    if isinstance(cfg.get("cycle"), Mapping) and "name" in cfg["cycle"]:  # (none: the default's, NEDC)
        cfg["cycle"] = {**cfg["cycle"], "name": cycle(cfg["cycle"]["name"])}
    entries = cfg.get("disciplines")
    for i, e in enumerate(entries if isinstance(entries, list) else []):
        if not (isinstance(e, Mapping) and e.get("name") in ("energy", "cycle_range") and not e.get("class")
                and isinstance(e.get("options"), Mapping)):
            continue
        opts = dict(e["options"])
        if "cycle" in opts:
            opts["cycle"] = cycle(opts["cycle"])
        if isinstance(opts.get("cycle_weights"), Mapping):
            opts["cycle_weights"] = {cycle(k): w for k, w in opts["cycle_weights"].items()}
        entries[i] = {**e, "options": opts}
    v = cfg.get("vehicle")
    if isinstance(v, Mapping) and params.is_parameter_set_file(v.get("parameter_set")):
        cfg["vehicle"] = {**v, "parameter_set": at(v["parameter_set"])}
    if isinstance(cfg.get("ros"), Mapping) and isinstance(cfg["ros"].get("sign_key_file"), str):
        cfg["ros"] = {**cfg["ros"], "sign_key_file": at(cfg["ros"]["sign_key_file"])}
    cfg["search_path"] = search_path(cfg.get("search_path"), base)
    return cfg


def engine_section(value: Any, defaults: Mapping[str, Any], where: str) -> dict:
    if value is None:
        value = {}
    if isinstance(value, str) and where == "optimizer":
        value = {"name": value}
    if not isinstance(value, Mapping):
        raise ValueError(f"{where} must be a mapping with keys {sorted(defaults)}")
    check_keys(where, value, defaults)
    return {**copy.deepcopy(dict(defaults)), **dict(value)}


def check_mda_numbers(mda: Mapping[str, Any]) -> None:
    tol, it, w = mda["tolerance"], mda["max_iterations"], mda["relaxation"]
    if not is_number(tol) or not tol > 0:
        raise ValueError(f"mda.tolerance {tol!r} must be a number > 0{text_hint(tol)}")
    if isinstance(it, bool) or not isinstance(it, int) or it < 1:
        raise ValueError(f"mda.max_iterations {it!r} must be an integer >= 1")
    if not is_number(w) or not 0 < w <= 2:
        raise ValueError(f"mda.relaxation {w!r} must be in (0, 2]{text_hint(w)}")
    if not isinstance(mda["warm_start"], bool) and mda["warm_start"] not in ("auto", "tangent"):
        raise ValueError(f"mda.warm_start {mda['warm_start']!r} must be true, false, auto or tangent")
    if mda["warm_start"] == "tangent" and mda["method"] != "newton":
        raise ValueError(f"mda.warm_start tangent needs mda.method newton, not {mda['method']}")
    if not isinstance(mda["fuse_downstream"], bool):
        raise ValueError(f"mda.fuse_downstream {mda['fuse_downstream']!r} must be true or false")


def _parameter_set(cfg: dict) -> None:
    """``vehicle.parameter_set``: a set fitted for one energy model (its ``energy_model``, written by
    ``bev-mdo calibrate``) is refused on another (the chain's constants mean nothing to the
    quasi-static model). A set named by its file (``mine.yaml``) is read once, here, and its values
    go into the vehicle section as defaults (keys given there still win), so the resolved config
    reproduces the run alone: a bag's ``resume``, a node started in another folder or on another
    host, the same run after the file moved or was rewritten; ``parameter_set_source`` records which set
    that was (:func:`params.parameter_set_source`). A shipped set stays named (it comes with the package,
    whose version the bag records)."""
    v = cfg.get("vehicle")
    name = v.get("parameter_set") if isinstance(v, Mapping) else None
    fitted = params.fitted_for_another_model(name, cfg.get("energy_model")) if name is not None else None
    if fitted:
        raise ValueError(f"vehicle.parameter_set {name!r} was fitted for energy_model {fitted}, "
                         f"not {cfg.get('energy_model')}")
    for note in params.parameter_set_source(name)["notes"] if name is not None else ():  # said once per command
        warnings.warn(f"vehicle.parameter_set {name}: its fit noted: {note}", CycleNote, stacklevel=2)
    if not params.is_parameter_set_file(name):
        return
    values = params.load_parameter_set(name)
    replaced = params.ROAD_LOAD_REPLACES if "road_load" in v or any(
        k.startswith("road_load_") for k in v) else ()  # unused beside a road load, and refused there
    section = {k: x for k, x in v.items() if k != "parameter_set"}
    source = {k: x for k, x in params.parameter_set_source(name).items() if k in params.SOURCE_KEYS}
    cfg["vehicle"] = {**{k: x for k, x in values.items() if k not in section and k not in replaced}, **section,
                      "parameter_set_source": source}  # which set: its name, file, SHA-256 and fit date


def cycle_names(cfg: Mapping) -> dict[str, str]:
    """Each drive cycle a config names (``cycle.name``, the energy and cycle_range options ``cycle`` and
    ``cycle_weights``) -> the first key naming it (``disciplines[1].options.cycle_weights``)."""
    names = {cfg["cycle"]["name"]: "cycle.name"}
    for i, e in enumerate(cfg.get("disciplines") or []):
        if isinstance(e, Mapping) and e.get("name") in ("energy", "cycle_range") and not e.get("class"):
            opts = e.get("options") if isinstance(e.get("options"), Mapping) else {}  # else refused later
            one, weights = opts.get("cycle"), opts.get("cycle_weights")
            for name, key in [*([(one, "cycle")] if isinstance(one, str) else []),
                              *((str(k), "cycle_weights") for k in (weights if isinstance(weights, Mapping) else ()))]:
                names.setdefault(name, f"disciplines[{i}].options.{key}")
    return names


def _record_cycle_traces(cfg: dict) -> None:
    """Every drive-cycle CSV the run names (``cycle.name``, the energy and cycle_range options ``cycle``
    and ``cycle_weights``) is read once, here, into the resolved config's ``cycle_traces`` (path ->
    {time_s, speed_m_s}); the models take it from there, so a bag's ``resume`` and nodes started in
    another folder or on another host run on the same trace without the file. A trace already there
    (a resolved config read again) is checked, not re-read: whether the config fits is ``check_traces_fit``'s
    question for the traces read from a file."""
    traces = cfg.get("cycle_traces") or {}
    if not isinstance(traces, Mapping):
        raise ValueError("cycle_traces must map CSV paths to {time_s: [...], speed_m_s: [...]}")
    out = {}
    for name, where in ((n, w) for n, w in cycle_names(cfg).items() if is_csv_cycle(n)):
        if name in traces:  # a resolved config read again: check what it holds
            cycle, out[name] = trace_cycle(name, traces[name]), traces[name]
            if stale := _stored_trace_note(name, cycle):
                warnings.warn(stale, CycleNote, stacklevel=2)
        else:  # read (and checked) from the file
            try:
                cycle = load_cycle(name)
            except ValueError as exc:  # the key that names it: an options cycle is not `cycle:`
                raise ValueError(f"{where}: {exc}" if where != "cycle.name" else str(exc)) from None
            out[name] = trace_record(cycle)
        note = unbalanced_note(cycle, name)
        if note:
            warnings.warn(note, CycleNote, stacklevel=2)
    if out:
        cfg["cycle_traces"] = out
    else:
        cfg.pop("cycle_traces", None)


def _stored_trace_note(name: str, stored) -> str | None:
    """A note when the CSV file ``name`` (a relative name counts from the working directory) exists and its
    trace is not the ``stored`` one ``cycle_traces`` holds: the stored trace runs (a bag's resume and its nodes
    rely on it), but a user who edited the file since would otherwise get the old trace's energies with no
    word (11.99 km stored against 14.39 km on disk: 99.0 against 118.9 Wh/km). None when the file is absent
    or holds the same trace; a file that no longer reads as a cycle is said, not refused."""
    import numpy as np

    path = Path(name)
    if not path.is_file():
        return None

    def said(c) -> str:
        return f"{c.duration_s:g} s, {c.distance_m / 1e3:.4g} km"

    fix = f"to run the file, drop its cycle_traces entry ({name!r}) from the config"
    try:
        on_disk = load_cycle(name)
    except (ValueError, OSError) as exc:
        why = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        return f"{name}: cycle_traces stores a trace for this file ({said(stored)}), which runs; the file no longer " \
               f"reads as a cycle ({why}); {fix} once it does"
    same = on_disk.time_s.shape == stored.time_s.shape and np.allclose(on_disk.time_s, stored.time_s, rtol=1e-12, atol=0) \
        and np.allclose(on_disk.speed_m_s, stored.speed_m_s, rtol=1e-12, atol=1e-12)
    if same:
        return None
    return (f"{name}: the file's trace ({said(on_disk)}) is not the one cycle_traces stores for it ({said(stored)}); "
            f"the stored trace runs, as a bag's resume does; {fix}")


TRACE_RESERVE_BYTES = 64 * 1024  # of the YAML limit, for what a run adds to its resolved config (its key path)


def check_traces_fit(rest: dict, traces: Mapping[str, Any], read: Any) -> None:
    """ValueError (one line naming the CSV, its samples, what the whole config takes and the limit) when the
    resolved config (defaults filled), ``rest`` (plain, as a bag holds it) with ``traces`` as its ``cycle_traces``,
    would be YAML past
    ``yamlload.MAX_YAML_BYTES`` less ``TRACE_RESERVE_BYTES``: the run would go, but its bag could not be resumed
    or reported, nor its config read by a node (the YAML limits bound what untrusted text costs to parse,
    docs/security.md). Only traces ``read`` from a CSV by this load are checked: one a resolved config holds
    was checked when it was read, and the YAML limit bounds the config it came in (a run's resume)."""
    import yaml

    from bev_mdo.yamlload import MAX_YAML_BYTES

    read = [n for n in traces if n in read]
    if not read:
        return
    rest_bytes = len(yaml.safe_dump(rest, sort_keys=False).encode("utf-8"))  # a file's limit is in bytes
    chars = {n: trace_yaml_chars(r) + len(n) + 30 for n, r in traces.items()}  # with its key lines
    total = rest_bytes + sum(chars.values()) + TRACE_RESERVE_BYTES
    if total <= MAX_YAML_BYTES:
        return
    big = max(read, key=chars.get)
    n = len(traces[big]["time_s"])
    fits = max(0, int(n * (MAX_YAML_BYTES - (total - chars[big])) / chars[big]))
    said = "; ".join(f"{k} {len(traces[k]['time_s']):,} samples in {chars[k]:,} bytes" for k in traces)
    raise ValueError(f"{big}: with its {n:,} samples the run's resolved config would take {total:,} bytes of YAML "
                     f"(cycle_traces: {said}; the rest of the config {rest_bytes:,} bytes; {TRACE_RESERVE_BYTES // 1024} KiB "
                     f"kept for what a run adds), past the {MAX_YAML_BYTES:,} ({MAX_YAML_BYTES / 2**20:g} MiB) that its "
                     f"bag and nodes read back; at most about {fits:,} samples of this trace fit with the rest as it "
                     "is (resample it coarser)")


def validate_models(cfg: dict) -> dict[str, float]:
    """Vehicle and cycle sections are checked by the models' own validators; the vehicle's numeric
    parameters, defaults filled, are returned ({} when neither section is given: the defaults)."""
    vehicle: dict[str, float] = {}
    if "vehicle" in cfg or "cycle" in cfg:
        try:
            _parameter_set(cfg)
            vehicle = params.validate_vehicle(cfg.get("vehicle"))
            _chain_only(vehicle, cfg.get("energy_model"))
        except ValueError as exc:  # a key path (vehicle.x) says where already
            raise ValueError(str(exc) if str(exc).startswith("vehicle.") else f"vehicle: {exc}") from None
        try:
            cfg["cycle"] = params.validate_cycle(cfg.get("cycle"))
            from bev_mdo.disciplines.common import resampled_cycle

            _record_cycle_traces(cfg)
            resampled_cycle(cfg)  # read and check the trace now: one line naming file and row
        except ValueError as exc:
            raise ValueError(str(exc) if str(exc).startswith(("cycle.", "disciplines[")) else f"cycle: {exc}") from None
    return vehicle


def check_gear_order(vehicle: Mapping[str, float], problem) -> None:
    """With two speeds (``gear_count`` 2) the second, high-speed gear is the longer one
    (``params.gears_out_of_order``). One-line ValueError naming both where the fixed values, or a design
    variable's bounds, allow gear_ratio_2 above gear_ratio: such a box was evaluated (it shifts into a
    shorter gear at speed) and optimised over. Bounds that cross are refused, not constrained: the box
    then holds only real two-speed gearboxes and no evaluation is spent on others."""
    import numpy as np

    def span(name: str, side: int) -> tuple[float, str] | None:  # side 0: lowest value, 1: highest
        dv = next((d for d in problem.design_variables if d.name == name), None)
        if dv is not None:
            return ((dv.lower, f"the lower bound of problem.design_variables.{name}") if side == 0
                    else (dv.upper, f"the upper bound of problem.design_variables.{name}"))
        for where, values in (("problem.parameters", problem.parameters), ("vehicle", vehicle)):
            if name in values:
                a = np.asarray(values[name], dtype=float)
                return float(a.max() if side else a.min()), f"{where}.{name}"
        return None

    count, first, second = span("gear_count", 1), span("gear_ratio", 0), span("gear_ratio_2", 1)
    if None in (count, first, second) or not params.gears_out_of_order(count[0], first[0], second[0]):
        return
    raise ValueError(f"gear_ratio_2 {second[0]:g} ({second[1]}) is above gear_ratio {first[0]:g} ({first[1]}): "
                     + params.GEAR_ORDER)


# two_speed_efficiency_loss is left out: a fitted parameter set holds it (its fleet's two-speed cars), and a set
# file's values go into the vehicle section, where they would read as stated
TWO_SPEED_KEYS = ("gear_ratio_2", "shift_speed_m_s", "shift_strategy", "two_speed_added_mass_kg")


def two_speed_notes(cfg: Mapping[str, Any], vehicle: Mapping[str, float], problem) -> None:
    """A note (``CycleNote``, one line) where the two-speed gearbox keys the vehicle section states change nothing:
    on a topology other than SM-SA (gear_count 2 is SM-SA only), or with gear_count 1 and no design variable or
    problem parameter setting it (a DM-DA config with gear_ratio_2, shift_speed_m_s, shift_strategy and
    two_speed_added_mass_kg ran as if they were not there). A note, not an error: a sweep or --set may set
    gear_count 2. And where a two-speed box shifts by speed (shift_strategy 0) at a speed above the top speed of
    every cycle the run uses (80 'm/s' meant as km/h): the energy model never uses its second gear there."""
    import numpy as np

    section = cfg.get("vehicle") if isinstance(cfg.get("vehicle"), Mapping) else {}
    topology = params.vehicle_choice(section, "topology")
    values = {**vehicle, **problem.parameters}
    two = "gear_count" in problem.names or bool(np.any(np.asarray(values.get("gear_count", 1.0)) == 2.0))
    specs = params.all_specs()
    stated = [k for k in TWO_SPEED_KEYS if k in section and vehicle.get(k) != specs[k].default]
    if stated and (topology != "SM-SA" or not two):
        why = (f"a {topology} powertrain has no two-speed gearbox (gear_count 2 is SM-SA only)" if topology != "SM-SA"
               else "vehicle.gear_count is 1 (single speed)")
        warnings.warn(f"{', '.join('vehicle.' + k for k in stated)}: two-speed gearbox key{'s' if len(stated) > 1 else ''}"
                      f", but {why}: {'they change' if len(stated) > 1 else 'it changes'} nothing"
                      + (" unless a design sets gear_count 2" if topology == "SM-SA" else ""), CycleNote, stacklevel=2)
    if topology == "SM-SA" and two and "two_speed_efficiency_loss" not in (*problem.names, *problem.parameters):
        from bev_mdo.disciplines.common import platform_loss_note

        if (note := platform_loss_note(section)):
            warnings.warn(note, CycleNote, stacklevel=2)
    if (topology != "SM-SA" or not two or cfg.get("energy_model") != "quasi_static" or values.get("shift_strategy")
            or not isinstance(cfg.get("cycle"), Mapping)):
        return
    dv = next((d for d in problem.design_variables if d.name == "shift_speed_m_s"), None)
    shift, where = ((dv.lower, "the lower bound of problem.design_variables.shift_speed_m_s") if dv is not None else
                    (float(np.min(values.get("shift_speed_m_s", 68.1 / 3.6))), "problem.parameters.shift_speed_m_s"
                     if "shift_speed_m_s" in problem.parameters else "vehicle.shift_speed_m_s"))
    cycles = [load_cycle(n, cfg.get("cycle_traces")) for n in cycle_names(cfg)]
    if all(shift > float(np.max(c.speed_m_s)) for c in cycles):
        tops = ", ".join(f"{c.name} {c.max_speed_kmh:.1f} km/h" for c in cycles)
        warnings.warn(f"{where} {shift:g} m/s ({shift * 3.6:.0f} km/h) is above the top speed of every cycle the run "
                      f"uses ({tops}): the two-speed gearbox never shifts into its second gear on them (a speed in "
                      "km/h? this key is in m/s)", CycleNote, stacklevel=2)


def check_gear_order_per_design(vehicle: Mapping[str, float], problem, values: Mapping, where: str = "") -> None:
    """The same rule for designs given per point (``values``: numbers or arrays over the config's own
    values, e.g. a ``--set``, a sweep's columns or ``problem.baseline``): one-line ValueError naming the
    first design whose second gear is shorter than its first, after ``where``."""
    import numpy as np

    own = {**vehicle, **{d.name: d.initial for d in problem.design_variables}, **problem.parameters}
    count, first, second = np.broadcast_arrays(*(np.atleast_1d(np.asarray(values.get(k, own.get(k, np.nan)), float))
                                                 for k in ("gear_count", "gear_ratio", "gear_ratio_2")))
    bad = np.flatnonzero(params.gears_out_of_order(count, first, second))
    if bad.size:
        i = int(bad[0])
        raise ValueError(f"{where}gear_ratio_2 {second[i]:g} is above gear_ratio {first[i]:g}"
                         f"{f' (design {i + 1})' if count.size > 1 else ''}: {params.GEAR_ORDER}")


def _chain_only(vehicle: Mapping[str, float], energy_model: str | None) -> None:
    """A parameter only the chain model reads, set on another energy model, is refused: a van's 2 kW
    auxiliary load on the quasi-static model changed nothing, without a word."""
    if energy_model == "chain":
        return
    for k in params.CHAIN_ONLY:
        if vehicle[k] != params.CHAIN_SPECS[k].default:
            raise ValueError(f"vehicle.{k}: only energy_model chain reads it; this run's energy_model {energy_model} "
                             "has no such term (remove it, or use energy_model: chain)")


def vehicle_topology_into_options(cfg: dict) -> None:
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


def resolve_problem(section: Any) -> dict:
    """The problem section. Battery sized for range: ``battery_kwh`` leaves the design variables (its
    initial value becomes the MDA loop's starting guess; the ``battery_sizing`` discipline produces it)
    and the ``range_km`` constraint, met by construction, becomes ``monitor: true``."""
    if not isinstance(section, Mapping):
        raise ValueError("problem must be a mapping with objective, design_variables and constraints")
    prob = copy.deepcopy(dict(section))
    sized = prob.get("battery_sized_for_range", False)
    if not isinstance(sized, bool):
        raise ValueError(f"problem.battery_sized_for_range {sized!r} must be true or false")
    prob["battery_sized_for_range"] = sized
    dvs = prob.get("design_variables")
    if sized and isinstance(dvs, Mapping) and SIZED_VARIABLE in dvs:
        prob["design_variables"] = dvs = dict(dvs)
        spec = dvs.pop(SIZED_VARIABLE)
        if isinstance(spec, Mapping) and "initial" in spec:
            prob.setdefault("coupling_guesses", {}).setdefault(SIZED_VARIABLE, spec["initial"])
        if isinstance(spec, Mapping) and {"lower", "upper"} & set(spec):  # its bounds were dropped without a word
            bounds = ", ".join(f"{k} {spec[k]}" for k in ("lower", "upper") if k in spec)
            warnings.warn(f"problem.battery_sized_for_range: {SIZED_VARIABLE} is sized for the range target (the "
                          f"battery_sizing discipline), not a design variable: its {bounds} do not apply (to bound it, "
                          f"constrain {SIZED_VARIABLE} as an output under problem.constraints)", CycleNote, stacklevel=2)
    base = prob.get("baseline")
    if base is not None:
        if not isinstance(base, Mapping) or set(base) - {"name", "design"} or not isinstance(base.get("design"), Mapping):
            raise ValueError("problem.baseline must be {name: <label>, design: {<design variable>: <value>, ...}}")
        label = base.get("name", "baseline")
        if not isinstance(label, str) or not label.strip():
            raise ValueError("problem.baseline.name must be a non-empty label, e.g. 'Nissan Leaf'")
        design = {}
        for k, v in base["design"].items():
            if not is_number(v) or not math.isfinite(v):
                raise ValueError(f"problem.baseline.design.{k}: {v!r} must be a finite number{text_hint(v)}")
            if not (sized and k == SIZED_VARIABLE):  # sized mode: the battery is sized, not given
                design[str(k)] = float(v)
        prob["baseline"] = {"name": label.strip(), "design": design}
    cons = prob.get("constraints")
    if sized and isinstance(cons, Mapping) and isinstance(cons.get(SIZED_CONSTRAINT), Mapping):
        # battery_sizing meets the range target exactly; as an optimiser constraint it would duplicate
        # the consistency equality (rank-deficient in IDF), so it is only monitored
        prob["constraints"] = {**cons, SIZED_CONSTRAINT: {**cons[SIZED_CONSTRAINT], "monitor": True}}
    return prob

