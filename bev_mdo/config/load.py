"""Loading a run config (``RunConfig.load``): read the YAML, validate every section once, build the
run's disciplines. Code downstream takes the ``RunConfig``; a function given a plain mapping loads
it once with ``RunConfig.of``. Any problem raises a one-line ValueError naming the file and the key.
"""
from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from bev_mdo.config.disciplines import check_against_disciplines, discipline_entries, resolve_disciplines
from bev_mdo.config.sections import (anchor_paths, check_gear_order, check_gear_order_per_design, check_mda_numbers,
                                     check_optimizer_options, resolve_problem, search_path, engine_section,
                                     two_speed_notes, validate_models, vehicle_topology_into_options,
                                     check_traces_fit, note_missing_folders)
from bev_mdo.mdo.problem import Problem
from bev_mdo.mdo.settings import MDASettings, OptimizerSettings, RunSettings
from bev_mdo.mdo.vectors import has_partials
from bev_mdo.models.common import check_keys, is_number, text_hint
from bev_mdo.models.cycles import CycleNote
from bev_mdo.models.road_load import implausible_note
from bev_mdo.ros_settings import validate_ros

TOP_KEYS = ("name", "description", "vehicle", "cycle", "energy_model", "disciplines", "problem",
            "formulation", "mda", "optimizer", "ros", "recording", "search_path", "cycle_traces")
FORMULATIONS = ("mdf", "idf")
RECORDING_KEYS = ()  # nothing reads a key of the recording section yet: any key there would do nothing
# the engine sections' defaults, defined once with their types (mdo/settings.py)
MDA_DEFAULTS = MDASettings().as_dict()
OPTIMIZER_DEFAULTS = OptimizerSettings().as_dict()


@dataclass(frozen=True, eq=False, repr=False)
class RunConfig(Mapping):
    """A run config, validated once: read its typed parts, not the dictionary.

    ``data``: the resolved config as a plain dict (recorded in the run's log folder and bag; treat
    it as read-only); ``problem``: the ``Problem``; ``disciplines``: the run's discipline objects in
    their order (built once, at load); ``ros``: the ``ros:`` section with its defaults filled in;
    ``settings``: what the engine reads (problem, formulation, ``mda:``, ``optimizer:``, the
    disciplines by name and whether each has analytic partials); ``vehicle``: the numeric vehicle
    parameters, validated (defaults and a named parameter set filled). As a read-only mapping it is
    ``data`` (``config["vehicle"]``), for the discipline classes and other code that takes a
    config's sections as written.
    """

    data: dict
    problem: Problem
    disciplines: tuple
    ros: dict
    settings: RunSettings
    vehicle: Mapping[str, float]  # the vehicle's numeric parameters, defaults and a named parameter set filled
    source: str = "<config>"  # the file it was read from, which its errors name ('<config>': a mapping)

    @classmethod
    def load(cls, source: str | Path | Mapping[str, Any], edit=None, where: str | None = None) -> "RunConfig":
        """Read and validate a run config: a YAML path, or an already-parsed mapping (a resolved
        one, e.g. read back from a bag, loads to the same config).

        A file's relative paths count from its folder (``read_config_file``; a mapping's, from the
        working directory). ``search_path`` (where a discipline's ``module:Class`` is looked for,
        before Python's own path) becomes absolute: the config's own entries, then the config file's
        folder, then the working directory. A resolved config written elsewhere (a run's log folder,
        a bag) keeps them, so every process of a run resolves files and user modules the same way. ``edit(raw) -> raw`` changes the parsed mapping before it is checked
        (command-line overrides). ``where``: what its errors name for a mapping (default ``<config>``).
        """
        if isinstance(source, Mapping):
            where, raw = where or "<config>", copy.deepcopy(dict(source))
        else:
            where, raw = str(source), read_config_file(source)
        if edit is not None and isinstance(raw, Mapping):
            raw = edit(raw)
        try:
            if isinstance(raw, Mapping):
                raw = {**raw, "search_path": search_path(raw.get("search_path"), None)}
            return replace(_resolve(raw), source=where)
        except ValueError as exc:
            msg = str(exc).strip().splitlines()[0] if str(exc).strip() else "invalid config"
            raise ValueError(f"{where}: {msg}") from None

    @classmethod
    def of(cls, config: "RunConfig | Mapping[str, Any]") -> "RunConfig":
        """``config`` itself, or a plain mapping (a config dict) loaded once."""
        return config if isinstance(config, RunConfig) else cls.load(config)

    @property
    def name(self) -> str:
        return self.data["name"]

    @property
    def baseline(self) -> dict | None:
        """``problem.baseline`` ({name, design}), or None."""
        return self.data["problem"].get("baseline")

    @property
    def parameter_set(self) -> dict | None:
        """The vehicle's parameter set: ``{"name"}`` of a shipped one, or what ``vehicle.parameter_set_source``
        records of one given as a file (name, file, sha256, fitted: its values are in the section); None."""
        v = self.data.get("vehicle") or {}
        if isinstance(v.get("parameter_set_source"), Mapping):
            return dict(v["parameter_set_source"])
        return {"name": v["parameter_set"]} if isinstance(v.get("parameter_set"), str) else None

    @property
    def names(self) -> tuple[str, ...]:
        """The run's disciplines by name, in their order."""
        return self.settings.disciplines

    def with_ros(self, section: Mapping[str, Any]) -> "RunConfig":
        """The same run with another ``ros:`` section (checked; nothing else is parsed again)."""
        return replace(self, data={**self.data, "ros": dict(section)}, ros=validate_ros(section))

    def with_vehicle(self, values: Mapping[str, float]) -> "RunConfig":
        """The same run with numeric ``vehicle:`` values replaced (a node's ``-p vehicle.<key>``), checked;
        itself when none changes."""
        vehicle = dict(self.data.get("vehicle") or {})
        if all(vehicle.get(k) == v for k, v in values.items()):
            return self
        from bev_mdo.models.params import VEHICLE_CHOICES, validate_vehicle

        vehicle.update(values)  # validate_vehicle returns the numeric parameters; choices and the set's record are kept
        choices = {k: vehicle[k] for k in (*VEHICLE_CHOICES, "parameter_set_source") if k in vehicle}
        return RunConfig.load({**self.data, "vehicle": {**validate_vehicle(vehicle), **choices}}, where=self.source)

    def with_sections(self, **sections: Any) -> "RunConfig":
        """Another run config: this one's with whole sections replaced (``formulation="idf"``), loaded."""
        return RunConfig.load({**self.data, **sections}, where=self.source)

    def with_run_key(self, directory: Path) -> "RunConfig":
        """The same run signed with a fresh per-run key (``protocol.signing.with_run_key``), unless its
        ``ros:`` section names its own key or turns signing off."""
        from bev_mdo.protocol.signing import with_run_key

        keyed = with_run_key(self.data, directory)
        return self if keyed is self.data else self.with_ros(keyed["ros"])

    def timed_disciplines(self) -> list:
        """The disciplines as this process calls them, in every command: each ``prepare()`` run now, before
        any clock (one that raises is one line, as a constructor that raises), each call bounded by
        ``ros.timeout_s`` x (``ros.retries`` + 1), the budget a ROS run gives it (mdo/timed.py)."""
        from bev_mdo.mdo.discipline import first_error_line
        from bev_mdo.mdo.timed import TimedDiscipline

        discs = [TimedDiscipline(d, self.ros["timeout_s"] * (self.ros["retries"] + 1)) for d in self.disciplines]
        for d in discs:
            try:
                d.prepare()
            except Exception as exc:  # noqa: BLE001 - the user's code: named, one line
                raise ValueError(f"discipline {d.name!r}: prepare() failed: "
                                 f"{first_error_line(f'{type(exc).__name__}: {exc}')}") from None
        return discs

    def entries(self) -> list[dict]:
        """``{name, class, options}`` of every discipline (what a node needs to build one)."""
        return discipline_entries(self.data, self.disciplines)

    def __getitem__(self, key: str) -> Any:
        return self.data[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.data)

    def __len__(self) -> int:
        return len(self.data)

    def __repr__(self) -> str:
        return f"RunConfig(name={self.name!r}, disciplines={list(self.names)})"


def read_config_file(path: str | Path) -> Any:
    """The parsed YAML of a config file, its relative paths counted from its folder (``anchor_paths``: a
    command-line override given after this counts from the working directory). One-line ValueErrors
    naming the file: missing, a directory, binary, too big, too deep, an alias bomb, bad YAML."""
    from bev_mdo.yamlload import read_yaml_file

    p = Path(path)
    if p.is_dir():
        raise ValueError(f"{p}: is a directory, not a config file; give the path of a config YAML file")
    if not p.is_file():
        raise ValueError(f"{p}: no such config file")
    raw = read_yaml_file(p)
    try:
        return anchor_paths(raw, p.resolve().parent) if isinstance(raw, Mapping) else raw
    except ValueError as exc:
        raise ValueError(f"{p}: {exc}") from None


def recorded_text(path: str | Path) -> str:
    """The text of config file `path` that a recorder started with it stores in its bag: as written when every
    path in it is already absolute (a run's resolved config), else ``read_config_file``'s (its relative paths,
    ``search_path`` among them, made absolute as the nodes read them), so a reader of the bag run from another
    folder finds the user's modules and files."""
    import yaml

    from bev_mdo.yamlload import load_yaml

    raw = read_config_file(path)  # (one-line errors naming the file)
    text = Path(path).read_text(encoding="utf-8")
    if not isinstance(raw, Mapping):
        return text
    given = load_yaml(text)
    absolute = isinstance(given.get("search_path"), list) and all(
        isinstance(d, str) and Path(d).is_absolute() for d in given["search_path"])
    if absolute and raw == {**given, "search_path": raw["search_path"]}:
        return text
    return yaml.safe_dump(plain(raw), sort_keys=False)


def load_config(path: str | Path | Mapping[str, Any], edit=None) -> dict:
    """The resolved config of ``RunConfig.load(path, edit)`` as a plain dict (``.data``)."""
    return RunConfig.load(path, edit).data


def check_run_name(name: Any) -> None:
    """A run's ``name`` becomes part of its bag and log folder names: ValueError unless it is a plain
    name (no path separator, not '.' or '..', no control character, at most 100 characters)."""
    if isinstance(name, bool):
        raise ValueError(f"name {name!r} is read by YAML as a boolean (yes/no/on/off too), not text: quote it")
    if isinstance(name, (int, float)):  # 12345 was told it may be "letters, digits, ..."
        kind = "an integer" if isinstance(name, int) else "a number"
        raise ValueError(f"name {name!r} is read by YAML as {kind}, not text: quote it (name: '{name}')")
    bad = (not isinstance(name, str) or not name.strip() or "/" in name or "\\" in name or name in (".", "..")
           or ".." in name or len(name) > 100 or any(ord(c) < 32 for c in name))
    if bad:
        raise ValueError(f"name {name!r} must be a plain run name (letters, digits, '-', '_', '.'; no path "
                         "separator, no '..', at most 100 characters): it names the run's bag and log folders")


def _resolve(raw: Any) -> RunConfig:
    from bev_mdo.disciplines import ENERGY_MODELS
    from bev_mdo.mdo.formulations import DERIVATIVES, FD_SCHEMES
    from bev_mdo.mdo.mda import METHODS
    from bev_mdo.mdo.optimizers import canonical_name

    if not isinstance(raw, Mapping):
        raise ValueError("the config must be a YAML mapping of sections (name, vehicle, cycle, problem, ...)")
    check_keys("", raw, TOP_KEYS)
    cfg = dict(raw)
    cfg.setdefault("name", "run")
    check_run_name(cfg["name"])
    if cfg.get("description") is not None and not isinstance(cfg["description"], str):
        raise ValueError(f"description must be text, got {type(cfg['description']).__name__}")
    for key in ("vehicle", "cycle", "disciplines", "ros", "recording"):  # one line, not a TypeError further in
        kind = "list" if key == "disciplines" else "mapping"
        if cfg.get(key) is not None and not isinstance(cfg[key], list if kind == "list" else Mapping):
            raise ValueError(f"{key} must be a {kind}")
    cfg["energy_model"] = cfg.get("energy_model", "flat")
    if cfg["energy_model"] not in ENERGY_MODELS:
        raise ValueError(f"energy_model {cfg['energy_model']!r} is unknown; allowed: {', '.join(ENERGY_MODELS)}")
    if not (isinstance(cfg.get("cycle"), Mapping) and "name" in cfg["cycle"]) and _reads_cycle(cfg):
        warnings.warn("cycle.name: not in the config: the NEDC, the thesis' cycle", CycleNote, stacklevel=2)
    vehicle = validate_models(cfg)
    vehicle_topology_into_options(cfg)
    cfg["formulation"] = str(cfg.get("formulation", "mdf")).lower()
    if cfg["formulation"] not in FORMULATIONS:
        raise ValueError(f"formulation {raw.get('formulation')!r} is unknown; allowed: {', '.join(FORMULATIONS)}")
    cfg["mda"] = engine_section(cfg.get("mda"), MDA_DEFAULTS, "mda")
    if cfg["mda"]["method"] not in METHODS:
        raise ValueError(f"mda.method {cfg['mda']['method']!r} is unknown; allowed: {', '.join(METHODS)}")
    cfg["optimizer"] = engine_section(cfg.get("optimizer"), OPTIMIZER_DEFAULTS, "optimizer")
    cfg["optimizer"]["name"] = canonical_name(cfg["optimizer"]["name"])
    if not isinstance(cfg["optimizer"]["options"], Mapping):
        raise ValueError("optimizer.options must be a mapping of the optimiser's own options")
    check_optimizer_options(cfg["optimizer"]["name"], cfg["optimizer"]["options"])
    if cfg["optimizer"]["fd_scheme"] not in FD_SCHEMES:
        raise ValueError(f"optimizer.fd_scheme {cfg['optimizer']['fd_scheme']!r} is unknown; allowed: "
                         f"{', '.join(FD_SCHEMES)}")
    step = cfg["optimizer"]["fd_step"]
    if not is_number(step) or not 0 < step < 0.1:
        raise ValueError(f"optimizer.fd_step {step!r} must be in (0, 0.1) (scaled units){text_hint(step)}")
    cfg["optimizer"]["fd_step"] = float(step)
    tol = cfg["optimizer"]["feasibility_tolerance"]
    if not is_number(tol) or not 0 <= tol < 1 or math.isnan(tol):
        raise ValueError(f"optimizer.feasibility_tolerance {tol!r} must be a number in [0, 1) "
                         f"(on normalised constraints; default 1e-4){text_hint(tol)}")
    cfg["optimizer"]["feasibility_tolerance"] = float(tol)
    if cfg["optimizer"]["derivatives"] not in DERIVATIVES:
        raise ValueError(f"optimizer.derivatives {cfg['optimizer']['derivatives']!r} is unknown; allowed: "
                         f"{', '.join(DERIVATIVES)}")
    for key in ("ros", "recording"):
        cfg[key] = dict(cfg.get(key) or {})
    check_keys("recording", cfg["recording"], RECORDING_KEYS)
    ros = validate_ros(cfg["ros"])  # checked here so the error names the file; the section is kept as written
    cfg["problem"] = resolve_problem(cfg.get("problem"))
    problem = Problem.from_config(cfg["problem"])
    check_gear_order(vehicle, problem)
    two_speed_notes(cfg, vehicle, problem)
    # numeric checks of the engine sections, by constructing the pieces once
    check_mda_numbers(cfg["mda"])
    discs = tuple(resolve_disciplines(cfg))
    note_missing_folders(cfg.get("search_path"))
    params = check_against_disciplines(cfg, problem, discs)
    leaf_defaults_note(cfg, problem, params)
    if (note := implausible_note(vehicle)):
        warnings.warn(f"vehicle.road_load: {note}", CycleNote, stacklevel=2)
    if cfg["problem"].get("baseline") is not None:
        problem.check_design(cfg["problem"]["baseline"]["design"], params, "problem.baseline.design")
        check_gear_order_per_design(vehicle, problem, cfg["problem"]["baseline"]["design"], "problem.baseline.design: ")
    recorded = raw.get("cycle_traces") if isinstance(raw.get("cycle_traces"), Mapping) else {}
    read = [n for n in cfg.get("cycle_traces") or () if n not in recorded]
    if read:  # the whole config, defaults filled, as a bag and a node's file hold it
        check_traces_fit(plain({k: v for k, v in cfg.items() if k != "cycle_traces"}), cfg["cycle_traces"], read)
    return RunConfig(cfg, problem, discs, ros, _settings(cfg, problem, discs), vehicle)


def _reads_cycle(cfg: Mapping) -> bool:
    """Whether a built-in discipline of ``cfg`` reads ``cycle.name`` (energy or cycle_range without a cycle option of
    its own, motor_speed; no disciplines: the default set): `cycle:` left empty ran the NEDC with no word."""
    entries = cfg.get("disciplines") if isinstance(cfg.get("disciplines"), list) else ["motor_speed"]
    named = [(e, {}) if isinstance(e, str) else (e.get("name"), e.get("options") or {}) for e in entries
             if isinstance(e, str) or isinstance(e, Mapping) and not e.get("class")]
    return any(n == "motor_speed" or n in ("energy", "cycle_range") and isinstance(o, Mapping)
               and not ({"cycle", "cycle_weights"} & set(o)) for n, o in named)


def leaf_defaults_note(cfg: Mapping[str, Any], problem, read: set[str]) -> None:
    """A note (``CycleNote``, one line) naming the constants that make a car its own (its mass, wheel and road
    load) where the run's disciplines read them and the config leaves them to the defaults, the thesis' Nissan
    Leaf: a Kona config without ``road_load`` ran on the Leaf's drag (117 Wh/km, not 134) and said nothing."""
    import warnings

    from bev_mdo.models.cycles import CycleNote
    from bev_mdo.models.params import all_specs, vehicle_choice

    section = cfg.get("vehicle") if isinstance(cfg.get("vehicle"), Mapping) else {}
    given = {*section, *problem.names, *problem.parameters}
    mass = "glider_kg" if vehicle_choice(section, "mass_model") == "ch7" else "kerb_reference_kg"
    road_load = "road_load" in given or any(k.startswith("road_load_") for k in given)
    keys = [mass, "wheel_radius_m", *(() if road_load else ("drag_area_m2", "rolling_resistance"))]
    specs = all_specs()
    left = [f"{k} {specs[k].default:g} {specs[k].unit}".replace(" -", "") for k in keys if k in read and k not in given]
    if left:
        warnings.warn(f"vehicle: {', '.join(left)}: not in the config: the thesis' Nissan Leaf's values, where a run "
                      "does not set them", CycleNote, stacklevel=2)


def _settings(config: dict, problem: Problem, discs) -> RunSettings:
    """The engine's typed settings: problem, formulation, the ``mda:``/``optimizer:`` sections, the
    disciplines by name and whether each provides analytic partials, and the disciplines' judgement of a
    design beyond its constraints (whether its motor follows the cycle; the driver imports nothing above
    the engine)."""
    from bev_mdo.disciplines.energy import follow_batch, follow_check

    return RunSettings(config["problem"], str(config["formulation"]), MDASettings.of(config["mda"]),
                       OptimizerSettings.of(config["optimizer"]), tuple(d.name for d in discs),
                       {d.name: bool(has_partials(d)) for d in discs}, parsed_problem=problem,
                       design_check=follow_check(discs), designs_check=follow_batch(discs))


def run_settings(config: RunConfig | Mapping[str, Any]) -> RunSettings:
    """The engine's typed settings of a run config (``RunConfig.of(config).settings``)."""
    return RunConfig.of(config).settings


def plain(obj):
    """YAML-safe copy of a config (numpy scalars to floats, tuples to lists)."""
    if isinstance(obj, RunConfig):
        return plain(obj.data)
    if isinstance(obj, dict):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if hasattr(obj, "item"):
        return obj.item()
    return obj
