"""Overrides of a run config's problem, shared by the API and every command that runs designs.

``Overrides`` holds them; on the command line (``from_args``) they are ``--bound NAME=LO:HI`` (either
side may be left out: ``motor_kw=:100``), ``--initial NAME=X``, ``--constraint "NAME>=X"`` / ``"NAME<=X"``,
``--objective NAME`` and ``--maximize`` / ``--minimize``. They edit the config's ``problem`` section
before it is validated (load_config's ``edit`` hook), so a run sees, checks and records exactly the
effective values. An unknown name is an InputError naming the nearest valid one.
"""
from __future__ import annotations

import copy
import difflib
import math
import numbers
import re
import sys
from dataclasses import dataclass, field
from typing import Any, Mapping

from bev_mdo.api.errors import InputError

_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][\w\[\]\.]*)\s*(>=|<=)\s*(\S.*?)\s*$")


@dataclass
class Overrides:
    """Edits of a config's problem: bounds {name: (lower or None, upper or None)}, initial values,
    constraints {output: {"lower": x} and/or {"upper": x}}, the objective and its sense."""

    bounds: dict[str, tuple[float | None, float | None]] = field(default_factory=dict)
    initial: dict[str, float] = field(default_factory=dict)
    constraints: dict[str, dict[str, float]] = field(default_factory=dict)
    objective: str | None = None
    maximize: bool | None = None

    def __bool__(self) -> bool:
        return bool(self.bounds or self.initial or self.constraints or self.objective is not None
                    or self.maximize is not None)


def from_args(args) -> Overrides:
    """The overrides of a parsed command line (add_override_arguments), from its text: ``NAME=LO:HI``,
    ``NAME=X``, ``'NAME>=X'`` / ``'NAME<=X'``, the objective and its sense."""
    ov = Overrides(objective=getattr(args, "objective", None), maximize=getattr(args, "maximize", None))
    for item in getattr(args, "bound", None) or []:
        name, sep, spec = (part.strip() for part in item.partition("="))
        lo, colon, hi = (part.strip() for part in spec.partition(":"))
        if not sep or not colon or not name or not (lo or hi):
            raise InputError(f"--bound {item!r} must be NAME=LO:HI (LO or HI may be left out)")
        old_lo, old_hi = ov.bounds.get(name, (None, None))
        ov.bounds[name] = (_number(lo, "--bound", item) if lo else old_lo,
                           _number(hi, "--bound", item) if hi else old_hi)
    for item in getattr(args, "initial", None) or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise InputError(f"--initial {item!r} must be NAME=X")
        ov.initial[name.strip()] = _number(value.strip(), "--initial", item)
    for item in getattr(args, "constraint", None) or []:
        m = _CONSTRAINT.match(item)
        if not m:
            raise InputError(f"--constraint {item!r} must be 'NAME>=X' or 'NAME<=X'")
        name, op, value = m.groups()
        ov.constraints.setdefault(name, {})["lower" if op == ">=" else "upper"] = _number(value, "--constraint", item)
    return ov


def real_number(value) -> bool:
    """Whether ``value`` is a number (numpy's too) and not a bool (True is not 1), a string ("4" is not 4), None
    or a list: the one rule for a number a user gives in code (Study's limits, design values, start points)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def finite_values(values: Mapping[str, Any], where: str = "", one: str = "") -> None:
    """InputError naming the first design variable or parameter of ``values`` whose value (a number or
    an array of numbers) is NaN or infinite, or not a number (real_number: None, "3", True): the one check of
    every design a user gives (--set, --design, --at, --vary, --list; Study.evaluate, optimize's x0, sweep,
    sensitivity). Such a value was evaluated to NaN outputs, or sent in a batch whose rows came back NaN,
    instead of being refused (None was named as nan; "3" and True were taken as 3 and 1). ``where``: the flag,
    if any; ``one``: the values are one design (a number each), and what to say to a list (a list reached
    float() as a TypeError)."""
    import numpy as np

    for name, value in values.items():
        head = f"{where + ' ' if where else ''}{name}={value!r}"
        if one and np.ndim(value) != 0:
            raise InputError(f"{head}: {one}")
        try:
            numeric = isinstance(value, np.ndarray) and value.dtype.kind in "fiu"  # a large DOE's columns
            if not numeric and not all(map(real_number, np.asarray(value, dtype=object).flat)):
                raise TypeError
            a = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{head}: must be a number") from None
        bad = a[~np.isfinite(a)]
        if bad.size:
            raise InputError(f"{where + ' ' if where else ''}{name}={bad.flat[0]:g}: a design value must be "
                             "a finite number")


def load(source, overrides: Overrides | None = None):
    """The validated config (``RunConfig``) of ``source`` (a file or a mapping) with ``overrides`` applied."""
    from bev_mdo.config import RunConfig

    written = RunConfig.load(source)  # the config as written must be valid first
    if not overrides:
        return written
    names = known_names(written)
    try:
        return RunConfig.load(source, edit=lambda raw: apply(raw, overrides, names))
    except InputError:
        raise
    except ValueError as exc:  # the file as written loads: the command line's values made it invalid
        raise InputError(f"{exc} (with the command line's --bound, --initial, --constraint or --objective)") from None


def known_names(config) -> dict[str, list[str]]:
    """{design: [design-variable names], outputs: [every discipline output]} of a ``RunConfig``."""
    from bev_mdo.config import RunConfig

    outputs = sorted({v for d in RunConfig.of(config).disciplines for v in d.outputs})
    outputs += sorted({v.split("[")[0] for v in outputs if "[" in v})
    return {"design": list((config["problem"].get("design_variables") or {})), "outputs": outputs}


def _element(name: str, dvs: Mapping, names: Mapping[str, list[str]], flag: str) -> tuple[str, int | None]:
    """(the design variable, the element's index or None) that ``name`` gives: ``motor_kw``, or ``h[1]`` of a
    vector ``h`` (``shape: 2`` in the config); InputError naming the nearest variable, or the vector's size."""
    from bev_mdo.mdo.vectors import base_name  # (numpy: loaded on first use)

    base = base_name(name)
    if base == name or base not in names["design"]:
        _check(name, names["design"], flag, "design variables")
        return name, None
    i = int(name[len(base) + 1:-1])  # base[i]
    size = (dvs.get(base) or {}).get("shape") if isinstance(dvs.get(base), Mapping) else None
    if not isinstance(size, int) or not 0 <= i < size:
        raise InputError(f"{flag} {name!r}: {base} is {'a scalar' if size is None else f'a vector of {size}'}"
                         f"{'' if size is None else f' (elements {base}[0] .. {base}[{size - 1}])'}")
    return base, i


def _edited(entry, i: int | None, values: Mapping[str, float]) -> dict:
    """A copy of a design variable's config entry with ``values`` set: the whole variable, or element ``i`` of a
    vector (one number for every element becomes a list of ``shape`` numbers)."""
    from bev_mdo.mdo.vectors import expand

    entry = dict(entry or {})
    for k, v in values.items():  # (the config as written is valid: a list holds ``shape`` values)
        entry[k] = v if i is None else [v if j == i else old for j, old in
                                        enumerate(expand(entry.get(k), int(entry["shape"]), k))]
    return entry


def _check(name: str, valid: list[str], flag: str, what: str) -> None:
    if name in valid:
        return
    near = difflib.get_close_matches(name, valid, n=1, cutoff=0.5)
    hint = f"; did you mean {near[0]!r}?" if near else f"; {what}: {', '.join(valid)}"
    one = what[:-1] if what.endswith("s") else what
    raise InputError(f"{flag} {name!r}: not {'an' if one[0] in 'aeiou' else 'a'} {one}{hint}")


def no_underscore(text: str, where: str) -> str:
    """``text``, a number typed on the command line, unless it holds an underscore: float() reads 1_00 as 100,
    a typo far more often than a grouping (InputError after ``where``: the flag and what was given)."""
    if "_" in text:
        raise InputError(f"{where}: an underscore in a number is taken for a typo; write the number without it")
    return text


def _number(text: str, flag: str, item: str) -> float:
    no_underscore(text, f"{flag} {item!r}")
    try:
        x = float(text)
    except ValueError:
        raise InputError(f"{flag} {item!r}: {text!r} is not a number") from None
    if not math.isfinite(x):  # nan, inf, 1e400: a limit nothing can meet or violate by a finite amount
        raise InputError(f"{flag} {item!r}: {text!r} must be finite")
    return x


def _clip_initials(dvs: dict, bounded: set[str], given: set[str]) -> None:
    """A variable (or a vector's element) given new bounds and no --initial (``bounded``, ``given``: the names as
    given, a vector's elements too) whose initial value is outside them starts at the nearest bound; one note on
    stderr says so."""
    from bev_mdo.mdo.vectors import base_name, expand

    for name in sorted(set(map(base_name, bounded))):
        e = dvs.get(name) or {}
        size = e.get("shape") if isinstance(e.get("shape"), int) else None
        try:  # each entry as a list of numbers (one number for every element); skipped where one is not a number
            x, lo, hi = ([float(v) if real_number(v) else None for v in expand(e.get(k), size or 1, "")]
                         for k in ("initial", "lower", "upper"))
        except ValueError:
            continue
        if None in (*x, *lo, *hi) or any(a > b for a, b in zip(lo, hi)):
            continue
        keep = {i for i in range(len(x)) if name in given or f"{name}[{i}]" in given}  # its own --initial
        moved = [v if i in keep else min(max(v, a), b) for i, (v, a, b) in enumerate(zip(x, lo, hi))]
        if moved == x:
            continue
        e["initial"] = moved if size is not None else moved[0]
        for i, (v, m, a, b) in enumerate(zip(x, moved, lo, hi)):
            if v != m:
                label = f"{name}[{i}]" if size is not None else name
                print(f"bev-mdo: note: {label} starts at {m:g}: its initial value {v:g} is outside "
                      f"--bound {a:g}:{b:g} (give --initial to choose)", file=sys.stderr)


def apply(raw: Mapping[str, Any], ov: Overrides, names: Mapping[str, list[str]]) -> dict:
    """A copy of the raw config mapping with the overrides written into its problem section."""
    raw = copy.deepcopy(dict(raw))
    prob = raw.setdefault("problem", {})
    if not isinstance(prob, dict):
        return raw  # the config's own check reports it
    dvs = prob.setdefault("design_variables", {})
    for name, (lo, hi) in ov.bounds.items():
        base, i = _element(name, dvs, names, "--bound")
        entry = _edited(dvs.get(base), i, {k: float(v) for k, v in (("lower", lo), ("upper", hi)) if v is not None})
        low, up = (entry.get(k) if i is None or not isinstance(entry.get(k), list) else entry[k][i]
                   for k in ("lower", "upper"))
        if all(isinstance(v, (int, float)) for v in (low, up)) and low >= up:
            said = ":".join("" if v is None else f"{v:g}" for v in (lo, hi))
            other = "" if None not in (lo, hi) else " (the other is the config file's)"
            raise InputError(f"--bound '{name}={said}': the lower bound {low:g} must be below the upper "
                             f"{up:g}{other}")
        dvs[base] = entry
    for name, value in ov.initial.items():
        base, i = _element(name, dvs, names, "--initial")
        dvs[base] = _edited(dvs.get(base), i, {"initial": float(value)})
    _clip_initials(dvs, set(ov.bounds), set(ov.initial))
    prob["constraints"] = cons = dict(prob.get("constraints") or {})
    for name, limits in ov.constraints.items():
        _check(name, names["outputs"], "--constraint", "outputs")
        cons[name] = {**dict(cons.get(name) or {}), **{k: float(v) for k, v in limits.items()}}
        size = sum(1 for v in names["outputs"] if v.startswith(f"{name}["))
        if size:  # a whole vector output: its limit holds for every element ("con<=0": con[0..k-1] <= 0)
            cons[name].setdefault("shape", size)
    if ov.objective is not None or ov.maximize is not None:
        current = prob.get("objective")
        old_name = current.get("name") if isinstance(current, Mapping) else current
        old_max = bool(current.get("maximize", False)) if isinstance(current, Mapping) else False
        if ov.objective is not None:
            _check(ov.objective, names["outputs"], "--objective", "outputs")
        new_max = old_max if ov.maximize is None else bool(ov.maximize)
        prob["objective"] = {"name": ov.objective or old_name, "maximize": True} if new_max else ov.objective or old_name
    return raw
