"""The optimisation problem: design variables, objective and constraints.

Constraints are normalised to g <= 0: a lower bound L on output y gives
(L - y) / s, an upper bound U gives (y - U) / s, with s = the constraint's
``scale`` (default max(|bound|, 1)). Margins are reported in physical units
(positive = satisfied). A constraint with ``monitor: true`` is reported but not
optimised against (used for range in battery-sized mode, where it holds by construction).

Vector variables (docs/vector-variables.md): a design variable or constraint with ``shape: k``
stands for k scalar elements named ``name[0]`` .. ``name[k-1]``; ``lower``, ``upper``,
``initial`` and ``scale`` are one number (every element) or a list of k numbers. The problem
holds the elements, so everything downstream (formulations, messages, history) is scalar.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bev_mdo.mdo.vectors import base_name, did_you_mean, expand, flat_names
from bev_mdo.models.common import check_keys, is_number, text_hint

MAX_VECTOR_ELEMENTS = 10_000  # per vector design variable or constraint (docs/vector-variables.md)
_DV_KEYS = {"lower", "upper", "initial", "scale", "shape"}
_CON_KEYS = {"lower", "upper", "scale", "monitor", "shape"}
PROBLEM_KEYS = {"objective", "objectives", "design_variables", "constraints", "battery_sized_for_range",
                "objective_scale", "parameters", "coupling_guesses", "coupling_bounds", "baseline"}
_OBJECTIVE_KEYS = {"name", "maximize"}


@dataclass(frozen=True)
class DesignVariable:
    name: str
    lower: float
    upper: float
    initial: float
    scale: float  # optimiser works in (x - lower) / scale; default upper - lower


@dataclass(frozen=True)
class Constraint:
    name: str
    lower: float | None = None
    upper: float | None = None
    scale: float | None = None
    monitor: bool = False  # reported with its margin, but not given to the optimiser

    def rows(self, monitored: bool = False) -> list[tuple[str, float, float]]:
        """(kind, bound, scale) per bound (kind 'lower' or 'upper'); none for a monitored constraint
        unless ``monitored``."""
        if self.monitor and not monitored:
            return []
        return [(kind, b, self.scale or max(abs(b), 1.0))
                for kind, b in (("lower", self.lower), ("upper", self.upper)) if b is not None]


@dataclass
class Problem:
    """Validated problem section of a run config."""

    objective: str
    design_variables: list[DesignVariable]
    constraints: list[Constraint] = field(default_factory=list)
    objective_scale: float = 1.0
    parameters: dict[str, float] = field(default_factory=dict)         # fixed model-parameter overrides
    coupling_guesses: dict[str, float] = field(default_factory=dict)   # MDA loop starting values
    coupling_bounds: dict[str, tuple[float, float]] = field(default_factory=dict)  # IDF bounds
    maximize: bool = False  # objective: {name: ..., maximize: true}; the optimisers minimise -f
    shapes: dict[str, int] = field(default_factory=dict)  # vector design variables / constraints -> size
    # ``objectives: [...]`` (bev-mdo pareto): (name, maximize) of each; empty when not given
    objectives: tuple[tuple[str, bool], ...] = ()

    @property
    def names(self) -> list[str]:
        return [d.name for d in self.design_variables]

    def coupling_guess(self, var: str, default: float = 1.0) -> float:
        """Loop starting value of a coupling element (its own entry, else its vector's)."""
        return self.coupling_guesses.get(var, self.coupling_guesses.get(base_name(var), default))

    def coupling_bound(self, var: str) -> tuple[float, float]:
        return self.coupling_bounds.get(var, self.coupling_bounds.get(base_name(var), (-np.inf, np.inf)))

    def outside_coupling_bounds(self, values: Mapping[str, float]) -> list[dict]:
        """The variables of ``values`` (an MDF result's outputs) beyond their ``coupling_bounds`` by more than 1e-6
        of the bound (at least 1e-6), as {"name", "kind", "bound", "value"}: those bound IDF's coupling variables,
        and MDF, whose couplings the MDA sets, does not apply them (its result says so)."""
        out = []
        for name, v in values.items():
            lo, hi = self.coupling_bound(name) if self.coupling_bounds else (-np.inf, np.inf)
            for kind, b, by in (("lower", lo, lo - v), ("upper", hi, v - hi)):
                if np.isfinite(b) and by > 1e-6 * max(1.0, abs(b)):
                    out.append({"name": name, "kind": kind, "bound": float(b), "value": float(v)})
        return out

    def array(self, attr: str) -> np.ndarray:
        return np.array([getattr(d, attr) for d in self.design_variables], dtype=float)

    @property
    def constraint_rows(self) -> list[tuple[str, str, float, float]]:
        """(output, kind, bound, scale) for every bound, in the order of the g vector."""
        return [(c.name, k, b, s) for c in self.constraints for k, b, s in c.rows()]

    @property
    def constraint_labels(self) -> list[str]:
        return [f"{n} {'>=' if k == 'lower' else '<='} {b:g}" for n, k, b, _ in self.constraint_rows]

    def constraint_outputs(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """The constrained outputs (N, m) in their own units, one column per bound (constraint_rows' order)."""
        cols = [np.asarray(values[name], dtype=float) for name, *_ in self.constraint_rows]
        n = len(np.atleast_1d(next(iter(values.values())))) if values else 0
        return np.column_stack(cols) if cols else np.zeros((n, 0))

    def g_terms(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(bound, sign, scale) per bound: g = sign (y - bound) / scale, sign -1 for a lower bound."""
        rows = self.constraint_rows
        return (np.array([b for _, _, b, _ in rows], dtype=float),
                np.array([-1.0 if k == "lower" else 1.0 for _, k, _, _ in rows]),
                np.array([s for *_, s in rows], dtype=float))

    def normalised(self, y: np.ndarray) -> np.ndarray:
        """Normalised constraints g (N, m) of constraint outputs y (N, m), feasible where <= 0."""
        bound, sign, scale = self.g_terms()
        return sign * (np.asarray(y, dtype=float) - bound) / scale

    def g(self, values: Mapping[str, np.ndarray]) -> np.ndarray:
        """Normalised constraints (N, m), feasible where <= 0."""
        return self.normalised(self.constraint_outputs(values))

    def design_dict(self, x: np.ndarray) -> dict[str, float]:
        return {n: float(v) for n, v in zip(self.names, np.asarray(x, dtype=float))}

    def x0(self) -> np.ndarray:
        return self.array("initial")

    def check_design(self, design: Mapping[str, Any], params, where: str = "design") -> None:
        """ValueError unless `design` gives every design variable and otherwise only names in `params`
        (the disciplines' parameters, which a design may override); `where` names it in the message."""
        missing = [n for n in self.names if n not in design]
        if missing:
            raise ValueError(f"{where} misses design variables {missing}; give every one of {self.names}")
        unknown = [k for k in design if k not in self.names and k not in params]
        if unknown:
            if (size := sum(n.startswith(f"{unknown[0]}[") for n in self.names)):  # t for the vector t[0] .. t[2]
                raise ValueError(f"{where}.{unknown[0]}: a vector of {size} elements: give each, {unknown[0]}[0] .. "
                                 f"{unknown[0]}[{size - 1}]")
            # a design variable first, nearer than the rest need be (gear for gear_ratio)
            hint = did_you_mean(unknown[0], self.names, 0.5) or did_you_mean(unknown[0], params)
            raise ValueError(f"{where}.{unknown[0]}: neither a design variable nor a discipline parameter; {hint}"
                             f"unknown design names {unknown}; design variables: {self.names}, "
                             f"parameters: {sorted(params)}")

    @classmethod
    def from_config(cls, section: Mapping[str, Any]) -> "Problem":
        """Build from the ``problem`` section; ValueError names the key and the allowed values."""
        if not isinstance(section, Mapping):
            raise ValueError("problem: must be a mapping with objective, design_variables, constraints")
        check_keys("problem", section, PROBLEM_KEYS)
        objectives = section.get("objectives")
        if objectives is not None:
            if not isinstance(objectives, list) or len(objectives) < 2:
                raise ValueError("problem.objectives: must list two or more outputs, each a name or "
                                 "{name: <output>, maximize: true}")
            objectives = tuple(parse_objective(o, f"problem.objectives[{i}]") for i, o in enumerate(objectives))
            twice = sorted({n for n, _ in objectives if [m for m, _ in objectives].count(n) > 1})
            if twice:
                raise ValueError(f"problem.objectives: {twice[0]!r} is named twice")
        # the single-objective commands optimise ``objective``, else the first of ``objectives``
        if "objective" in section or objectives is None:
            obj, maximize = parse_objective(section.get("objective"), "problem.objective")
        else:
            obj, maximize = objectives[0]
        dvs_raw = section.get("design_variables")
        if not isinstance(dvs_raw, Mapping) or not dvs_raw:
            raise ValueError("problem.design_variables: must map at least one name to {lower, upper, initial}")
        shapes: dict[str, int] = {}
        dvs = [d for n, spec in dvs_raw.items() for d in _elements(n, spec, _design_variable, shapes,
                                                                   "problem.design_variables")]
        cons_raw = section.get("constraints") or {}
        if not isinstance(cons_raw, Mapping):
            raise ValueError("problem.constraints: must map output names to {lower and/or upper}")
        cons = _merged([c for n, spec in cons_raw.items() for c in _elements(n, spec, _constraint, shapes,
                                                                             "problem.constraints")])
        oscale = _finite(section.get("objective_scale", 1.0), "problem.objective_scale")
        if oscale <= 0:
            raise ValueError(f"problem.objective_scale: {oscale} must be > 0")
        for key in ("parameters", "coupling_guesses", "coupling_bounds"):
            if not isinstance(section.get(key) or {}, Mapping):
                raise ValueError(f"problem.{key}: must be a mapping of variable names")
        params = {str(k): _num(v, f"problem.parameters.{k}") for k, v in (section.get("parameters") or {}).items()}
        guesses = {}
        for k, v in (section.get("coupling_guesses") or {}).items():
            if isinstance(v, (list, tuple)):  # a vector coupling, element by element
                for i, x in enumerate(v):
                    guesses[f"{k}[{i}]"] = _num(x, f"problem.coupling_guesses.{k}[{i}]")
            else:
                guesses[str(k)] = _num(v, f"problem.coupling_guesses.{k}")
        cb = {}
        for k, v in (section.get("coupling_bounds") or {}).items():
            if not isinstance(v, Mapping) or set(v) - {"lower", "upper"}:
                raise ValueError(f"problem.coupling_bounds.{k}: must be {{lower, upper}}")
            lo = _num(v.get("lower", -np.inf), f"problem.coupling_bounds.{k}.lower")
            hi = _num(v.get("upper", np.inf), f"problem.coupling_bounds.{k}.upper")
            if lo >= hi:
                raise ValueError(f"problem.coupling_bounds.{k}: lower {lo:g} must be < upper {hi:g}")
            cb[str(k)] = (lo, hi)
        return cls(obj, dvs, cons, oscale, params, guesses, cb, maximize=maximize, shapes=shapes,
                   objectives=objectives or ())


def parse_objective(value: Any, where: str) -> tuple[str, bool]:
    """(name, maximize) of an objective entry: an output name (minimised) or {name, maximize}."""
    maximize = False
    if isinstance(value, Mapping):
        check_keys(where, value, _OBJECTIVE_KEYS)
        maximize = value.get("maximize", False)
        if not isinstance(maximize, bool):
            raise ValueError(f"{where}.maximize: {maximize!r} must be true or false")
        value = value.get("name")
    if not isinstance(value, str) or not value:
        raise ValueError(f"{where}: must name one output (minimised), e.g. energy_wh_per_km, "
                         "or be {name: <output>, maximize: true}")
    return value, maximize


def _num(v: Any, where: str) -> float:
    if not is_number(v):
        raise ValueError(f"{where}: {v!r} must be a number{text_hint(v)}")
    if np.isnan(v):
        raise ValueError(f"{where}: must not be NaN")
    return float(v)


def _finite(v: Any, where: str) -> float:
    """A number that is neither NaN nor infinite (a limit or scale of inf would make every margin inf)."""
    x = _num(v, where)
    if not np.isfinite(x):
        raise ValueError(f"{where}: {x:g} must be finite")
    return x


def _elements(name: str, spec: Any, build, shapes: dict[str, int], section: str) -> list:
    """One entry, or one per element of a vector (``shape: k``; per-element values from lists)."""
    if not isinstance(spec, Mapping) or "shape" not in spec:
        if isinstance(spec, Mapping):
            lists = [k for k, v in spec.items() if isinstance(v, (list, tuple))]
            if lists:
                raise ValueError(f"{section}.{name}.{lists[0]}: a list needs shape: <number of elements>")
        return [build(str(name), spec, f"{section}.{name}")]
    where = f"{section}.{name}"
    size = spec["shape"]
    if isinstance(size, (list, tuple)) and len(size) == 1:
        size = size[0]
    if isinstance(size, bool) or not isinstance(size, int) or size < 1:
        raise ValueError(f"{where}.shape: {size!r} must be a positive integer (vectors only, e.g. shape: 6)")
    if size > MAX_VECTOR_ELEMENTS:
        raise ValueError(f"{where}.shape: {size} elements; a vector holds at most {MAX_VECTOR_ELEMENTS}")
    if name in shapes:
        raise ValueError(f"{where}: named twice")
    shapes[str(name)] = size
    per = {k: expand(v, size, f"{where}.{k}") for k, v in spec.items() if k != "shape"}
    out = []
    for i, flat in enumerate(flat_names(str(name), size)):
        try:
            out.append(build(flat, {k: v[i] for k, v in per.items()}, where=f"{where}[{i}]"))
        except ValueError as exc:
            raise ValueError(str(exc)) from None
    return out


def _design_variable(name: str, spec: Any, where: str) -> DesignVariable:
    if not isinstance(spec, Mapping):
        raise ValueError(f"{where}: must be a mapping {{lower, upper, initial[, scale]}}")
    check_keys(where, spec, _DV_KEYS)
    for k in ("lower", "upper"):
        if k not in spec:
            raise ValueError(f"{where}: missing {k!r}")
    lo, hi = _num(spec["lower"], f"{where}.lower"), _num(spec["upper"], f"{where}.upper")
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo >= hi:
        raise ValueError(f"{where}: bounds must be finite with lower < upper (got lower {lo:g}, upper {hi:g})")
    x0 = _num(spec.get("initial", 0.5 * (lo + hi)), f"{where}.initial")
    if not lo <= x0 <= hi:
        raise ValueError(f"{where}.initial: {x0:g} is outside the bounds [{lo:g}, {hi:g}]")
    scale = _finite(spec.get("scale", hi - lo), f"{where}.scale")
    if scale <= 0:
        raise ValueError(f"{where}.scale: {scale:g} must be > 0")
    check_resolved(f"{where}.initial", x0, lo, scale)
    return DesignVariable(str(name), lo, hi, x0, scale)


def check_resolved(where: str, x: float, lower: float, scale: float, rtol: float = 1e-6) -> None:
    """ValueError when the optimiser's variable u = (x - lower) / scale cannot hold ``x``: far wide bounds
    round it away (bounds +-1e20 turn an initial 1 into 0, and the end point was then checked at 0)."""
    back = lower + scale * ((x - lower) / scale)
    if abs(back - x) > rtol * abs(x):
        shifted = f"x - {lower:g}" if lower >= 0 else f"x + {-lower:g}"
        raise ValueError(f"{where}: {x:g} is lost to rounding in the optimiser's scaled variable ({shifted}) / "
                         f"{scale:g}, where it reads {back:g}: give bounds nearer the values the variable takes")


def _merged(cons: list[Constraint]) -> list[Constraint]:
    """One constraint per name: an element's own entry after its vector's (``sigma[0]: {upper: 300}`` beside
    ``sigma: {shape: 3, upper: 200}``, or ``--constraint "sigma[0]<=300"``) replaces the sides it gives (two
    entries kept both limits in force while reports showed one)."""
    out: dict[str, Constraint] = {}
    for c in cons:
        old = out.get(c.name)
        if old is not None:
            lo, hi = (c.lower if c.lower is not None else old.lower), (c.upper if c.upper is not None else old.upper)
            if lo is not None and hi is not None and lo > hi:
                raise ValueError(f"problem.constraints.{c.name}: lower {lo:g} > upper {hi:g} (with its vector's limit)")
            c = Constraint(c.name, lo, hi, c.scale if c.scale is not None else old.scale, c.monitor)
        out[c.name] = c
    return list(out.values())


def _constraint(name: str, spec: Any, where: str) -> Constraint:
    if not isinstance(spec, Mapping) or not spec:
        raise ValueError(f"{where}: must be a mapping with lower and/or upper")
    check_keys(where, spec, _CON_KEYS)
    lo = _finite(spec["lower"], f"{where}.lower") if "lower" in spec else None
    hi = _finite(spec["upper"], f"{where}.upper") if "upper" in spec else None
    if lo is None and hi is None:
        raise ValueError(f"{where}: needs lower and/or upper")
    if lo is not None and hi is not None and lo > hi:
        raise ValueError(f"{where}: lower {lo:g} > upper {hi:g}")
    scale = _finite(spec["scale"], f"{where}.scale") if "scale" in spec else None
    if scale is not None and scale <= 0:
        raise ValueError(f"{where}.scale: {scale:g} must be > 0")
    monitor = spec.get("monitor", False)
    if not isinstance(monitor, bool):
        raise ValueError(f"{where}.monitor: {monitor!r} must be true or false")
    return Constraint(str(name), lo, hi, scale, monitor)
