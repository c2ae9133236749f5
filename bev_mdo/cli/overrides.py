"""Command-line overrides of a run config's problem, shared by every command that runs designs.

``--bound NAME=LO:HI`` (either side may be left out: ``motor_kw=:100``), ``--initial NAME=X``,
``--constraint "NAME>=X"`` / ``"NAME<=X"``, ``--objective NAME`` and ``--maximize`` /
``--minimize`` edit the config's ``problem`` section before it is validated (load_config's
``edit`` hook), so a run sees, checks and records exactly the effective values. An unknown name
is a usage error naming the nearest valid one.
"""
from __future__ import annotations

import copy
import difflib
import re
from typing import Any, Mapping

from bev_mdo.cli import UsageError

_CONSTRAINT = re.compile(r"^\s*([A-Za-z_][\w\[\]\.]*)\s*(>=|<=)\s*(\S+)\s*$")


def add_override_arguments(parser) -> None:
    g = parser.add_argument_group("problem overrides (applied to the config before it is checked and recorded)")
    g.add_argument("--bound", action="append", default=[], metavar="NAME=LO:HI",
                   help="bounds of a design variable; LO or HI may be left out (motor_kw=:100)")
    g.add_argument("--initial", action="append", default=[], metavar="NAME=X", help="initial value of a design variable")
    g.add_argument("--constraint", action="append", default=[], metavar="'NAME>=X'",
                   help="add or change a constraint on an output: 'range_km>=250' or 'accel_time_0_100_s<=9'")
    g.add_argument("--objective", default=None, metavar="NAME", help="the output to optimise")
    sense = g.add_mutually_exclusive_group()
    sense.add_argument("--maximize", action="store_true", default=None, help="maximise the objective")
    sense.add_argument("--minimize", dest="maximize", action="store_false", help="minimise the objective")


def given(args) -> bool:
    """True when the command line overrides anything."""
    return bool(getattr(args, "bound", None) or getattr(args, "initial", None) or getattr(args, "constraint", None)
                or getattr(args, "objective", None) or getattr(args, "maximize", None) is not None)


def load(args, path=None) -> dict:
    """The validated config of ``path`` (default ``args.config``) with the command line's overrides applied."""
    from bev_mdo.config import load_config

    path = args.config if path is None else path
    if not given(args):
        return load_config(path)
    names = known_names(load_config(path))  # the config as written must be valid first
    return load_config(path, edit=lambda raw: apply(raw, args, names))


def known_names(config: Mapping[str, Any]) -> dict[str, list[str]]:
    """{design: [design-variable names], outputs: [every discipline output]} of a resolved config."""
    from bev_mdo.config import resolve_disciplines

    outputs = sorted({v for d in resolve_disciplines(config) for v in d.outputs})
    outputs += sorted({v.split("[")[0] for v in outputs if "[" in v})
    return {"design": list((config["problem"].get("design_variables") or {})), "outputs": outputs}


def _check(name: str, valid: list[str], flag: str, what: str) -> None:
    if name in valid:
        return
    near = difflib.get_close_matches(name, valid, n=1, cutoff=0.5)
    hint = f"; did you mean {near[0]!r}?" if near else f"; {what}: {', '.join(valid)}"
    one = what[:-1] if what.endswith("s") else what
    raise UsageError(f"{flag} {name!r}: not {'an' if one[0] in 'aeiou' else 'a'} {one}{hint}")


def _number(text: str, flag: str, item: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise UsageError(f"{flag} {item!r}: {text!r} is not a number") from None


def _clip_initials(dvs: dict, bounded: set[str]) -> None:
    """A variable given new bounds (and no --initial) that its initial value is outside of starts at
    the nearest bound; one note on stderr says so."""
    import sys

    for name in sorted(bounded):
        e = dvs.get(name) or {}
        x, lo, hi = e.get("initial"), e.get("lower"), e.get("upper")
        if not all(isinstance(v, (int, float)) for v in (x, lo, hi)) or lo > hi or lo <= x <= hi:
            continue
        e["initial"] = min(max(x, lo), hi)
        print(f"bev-mdo: note: {name} starts at {e['initial']:g}: its initial value {x:g} is outside "
              f"--bound {lo:g}:{hi:g} (give --initial to choose)", file=sys.stderr)


def apply(raw: dict, args, names: Mapping[str, list[str]]) -> dict:
    """A copy of the raw config mapping with the overrides written into its problem section."""
    raw = copy.deepcopy(dict(raw))
    prob = raw.setdefault("problem", {})
    if not isinstance(prob, dict):
        return raw  # the config's own check reports it
    dvs = prob.setdefault("design_variables", {})
    for item in getattr(args, "bound", []) or []:
        name, sep, spec = item.partition("=")
        lo, colon, hi = spec.partition(":")
        if not sep or not colon or not name.strip() or not (lo.strip() or hi.strip()):
            raise UsageError(f"--bound {item!r} must be NAME=LO:HI (LO or HI may be left out)")
        name = name.strip()
        _check(name, names["design"], "--bound", "design variables")
        entry = dict(dvs.get(name) or {})
        if lo.strip():
            entry["lower"] = _number(lo.strip(), "--bound", item)
        if hi.strip():
            entry["upper"] = _number(hi.strip(), "--bound", item)
        dvs[name] = entry
    for item in getattr(args, "initial", []) or []:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise UsageError(f"--initial {item!r} must be NAME=X")
        name = name.strip()
        _check(name, names["design"], "--initial", "design variables")
        dvs[name] = {**dict(dvs.get(name) or {}), "initial": _number(value.strip(), "--initial", item)}
    _clip_initials(dvs, {i.partition("=")[0].strip() for i in getattr(args, "bound", []) or []}
                   - {i.partition("=")[0].strip() for i in getattr(args, "initial", []) or []})
    cons = prob.get("constraints") or {}
    prob["constraints"] = cons = dict(cons)
    for item in getattr(args, "constraint", []) or []:
        m = _CONSTRAINT.match(item)
        if not m:
            raise UsageError(f"--constraint {item!r} must be 'NAME>=X' or 'NAME<=X'")
        name, op, value = m.groups()
        _check(name, names["outputs"], "--constraint", "outputs")
        entry = dict(cons.get(name) or {})
        entry["lower" if op == ">=" else "upper"] = _number(value, "--constraint", item)
        cons[name] = entry
    objective = getattr(args, "objective", None)
    maximize = getattr(args, "maximize", None)
    if objective is not None or maximize is not None:
        current = prob.get("objective")
        old_name = current.get("name") if isinstance(current, Mapping) else current
        old_max = bool(current.get("maximize", False)) if isinstance(current, Mapping) else False
        if objective is not None:
            _check(objective, names["outputs"], "--objective", "outputs")
        new_max = old_max if maximize is None else bool(maximize)
        new_name = objective or old_name
        prob["objective"] = {"name": new_name, "maximize": True} if new_max else new_name
    return raw
