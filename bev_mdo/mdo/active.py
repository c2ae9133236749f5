"""What holds a design where it is: active constraints, variables on a bound, blocking bounds.

Pure functions (no ROS, no evaluation of their own unless asked through ``fd_jacobian``). The rule
(active, violated, on a bound, blocks, conflicts, free way) is docs/answers.md, "The rule". Without a
Jacobian the infeasible analysis names the violated constraints and the variables on a bound but
cannot say which bound blocks.
"""
from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from bev_mdo.mdo.kinks import one_sided_descent
from bev_mdo.mdo.settings import FEASIBILITY_TOL  # the run's default tolerance on normalised constraints

REL_TOL = 1e-3
Disciplines = list | Callable[[], list]  # discipline objects, or a function building them


def _limits(problem) -> list[tuple[str, str, float, float]]:
    """(name, kind, limit, scale) for every bound of every constraint, monitored ones too."""
    return [(c.name, kind, float(b), float(s)) for c in problem.constraints for kind, b, s in c.rows(monitored=True)]


def analyse(problem, design: Mapping[str, float], values: Mapping[str, float], *,
            jacobian: Mapping[str, Mapping[str, float]] | None = None, rel_tol: float = REL_TOL,
            units: Mapping[str, str] | None = None, feas_tol: float = FEASIBILITY_TOL) -> dict[str, Any]:
    """The answers for one end point.

    ``problem``: a ``bev_mdo.mdo.problem.Problem``; ``design``: its design variables; ``values``: the
    constraint outputs at the point (extra keys are ignored); ``jacobian[output][variable]``: d output /
    d variable in physical units, one slope or (left, right) one-sided slopes (``fd_jacobian``'s: a kink's two
    sides differ), only needed for the blocking analysis of an infeasible end;
    ``units``: {variable: unit} as the disciplines declare them (mdo/units.py ``run_units``);
    ``feas_tol``: the run's feasibility tolerance (a normalised violation up to it is not "violated").
    Returns a JSON-ready dict: ``feasible``, ``active_constraints``, ``bounds`` (variables on a
    bound), ``outside_bounds`` (variables beyond a bound: such a point is infeasible), ``violated`` (each
    with ``blocked_by`` and ``conflicts_with`` when a Jacobian is given) and ``lines`` (the same as short
    sentences for the terminal).
    """
    from bev_mdo.mdo.units import unit_of

    def unit(name: str) -> str:
        return unit_of(name, units or {}, inline=True)
    active, violated = [], []
    for name, kind, limit, scale in _limits(problem):
        y = float(values.get(name, np.nan))
        v = limit - y if kind == "lower" else y - limit  # in the constraint's unit: > 0 violated
        entry = {"name": name, "kind": kind, "limit": limit, "value": y, "margin": -v + 0.0, "unit": unit(name),  # no -0
                 "scale": scale,
                 "monitor": any(c.monitor for c in problem.constraints if c.name == name)}
        if not np.isfinite(v):
            violated.append({**entry, "violation": float("inf")})
        elif v > feas_tol * scale:
            violated.append({**entry, "violation": v})
        elif abs(v) <= rel_tol * scale:
            active.append(entry)
    # an equality (lower == upper) is one limit, name == value: its two rows are merged, and the row on
    # the satisfied side of a violated one is not also an active limit
    equal = {c.name for c in problem.constraints if c.lower is not None and c.lower == c.upper}
    off = {e["name"] for e in violated if e["name"] in equal}
    violated = [e for e in violated if not (e["name"] in equal and e["kind"] == "upper" and np.isinf(e["violation"]))]
    active = [e for e in active if e["name"] not in off and not (e["name"] in equal and e["kind"] == "upper")]
    for e in active + violated:
        if e["name"] in equal:
            e["kind"], e["margin"] = "equal", -abs(e["margin"]) + 0.0
    bounds, outside = [], []
    for d in problem.design_variables:
        x = float(design[d.name])
        span = d.upper - d.lower
        for kind, b in (("lower", d.lower), ("upper", d.upper)):
            if abs(x - b) <= rel_tol * span:
                bounds.append({"name": d.name, "kind": kind, "bound": float(b), "value": x,
                               "margin": float(x - b if kind == "lower" else b - x), "unit": unit(d.name),
                               "scale": float(span)})
        outside += [{**b, "unit": unit(d.name)} for b in outside_bounds(d, x, feas_tol)]
    if jacobian is not None:
        on_bound = {**{b["name"]: b["kind"] for b in bounds}, **{b["name"]: b["kind"] for b in outside}}
        spans = {d.name: d.upper - d.lower for d in problem.design_variables}
        room = {d.name: tuple(min(max(r / (d.upper - d.lower), 0.0), 1.0) for r in  # (down, up) to the bounds
                              (float(design[d.name]) - d.lower, d.upper - float(design[d.name])))
                for d in problem.design_variables}
        for e in violated:
            sign = 1.0 if e["kind"] == "upper" or e["kind"] == "equal" and e["value"] > e["limit"] else -1.0
            grad = {n: tuple(sign * v for v in _sides(jacobian.get(e["name"], {}).get(n, 0.0))) for n in problem.names}
            # a bound blocks when the step beyond it would reduce the violation: its side's slope
            rate = {n: -g[1] if on_bound.get(n) == "upper" else g[0] for n, g in grad.items() if n in on_bound}
            blocking = [n for n, r in rate.items() if r > 0]
            e["blocked_by"] = [{"variable": n, "bound": on_bound[n], "rate": rate[n],
                                "rate_unit": f"{e['unit'] + ' ' if e['unit'] else ''}per {unit(n) or 'unit'}"} for n in blocking]
            e["blocked_by"].sort(key=lambda b: -b["rate"] * spans[b["variable"]])
            others = [o for o in violated if o is not e and np.isfinite(o["violation"])]
            held, reduction = _held_by(grad, active + others, jacobian, spans, on_bound, room)
            e["free_way"], e["free_way_reduction"] = reduction > 0.0, reduction  # in the constraint's unit
            e["conflicts_with"] = [_limit(a) for a in held if a in active]  # satisfied limits it would break
            e["trades_with"] = [_limit(o) for o in held if o in others]  # other violations it would worsen
    feasible = not any(not e["monitor"] for e in violated) and not outside
    out = {"feasible": feasible, "rel_tol": rel_tol, "active_constraints": active, "bounds": bounds,
           "outside_bounds": outside, "violated": violated}
    out["lines"] = summary_lines(out)
    return out


def outside_bounds(d, x: float, feas_tol: float) -> list[dict]:
    """The bound of design variable ``d`` (a problem's DesignVariable) that ``x`` lies beyond by more than
    ``feas_tol`` x (upper - lower), as {"name", "kind", "bound", "value", "by"}; [] inside. Such a point is
    infeasible whatever its constraints say (the answers, evaluate): COBYLA ended 6.5 % above a motor's upper
    bound, its violated constraints nearer their limits than any design inside the bounds can bring them."""
    span = d.upper - d.lower
    return [{"name": d.name, "kind": kind, "bound": float(b), "value": float(x), "by": float(by)}
            for kind, b, by in (("lower", d.lower, d.lower - x), ("upper", d.upper, x - d.upper))
            if by > feas_tol * span]


def outside_note(d, x: float) -> str:
    """The one line evaluate and a baseline give a design value ``x`` of ``d`` that ``outside_bounds`` finds."""
    return (f"{d.name} = {x:g} is outside its bounds [{d.lower:g}, {d.upper:g}]: infeasible whatever the "
            "constraints say (evaluated as given)")


OPERATORS = {"lower": ">=", "upper": "<=", "equal": "=="}


def _limit(e) -> str:
    return f"{e['name']} {OPERATORS[e['kind']]} {e['limit']:g}"


def _sides(v) -> tuple[float, float]:
    """(left, right) slopes of a Jacobian entry: one slope is both."""
    return (float(v), float(v)) if np.ndim(v) == 0 else (float(v[0]), float(v[1]))


def _held_by(grad, active, jacobian, spans, on_bound, room=None) -> tuple[list[dict], float]:
    """(the limits of ``active`` (active ones, and the other violated ones) that hold a violation, how much a
    first-order way reduces it within the bounds without worsening any of them, 0 for none): the linear program
    min grad_u v . du over steps du = p - q of the scaled variables, p and q in [0, room] (``room``: {variable:
    (down, up)}, the fractions of its range to its bounds, 0 on a bound: a variable 0.2 % below its upper bound
    reduces little by stepping up), that make none of them worse. p moves on the right-hand slope, q on the
    left-hand one (``grad``: {variable: (left, right)}): at a kink (a speed cap meeting a power limit, the cap's
    slope one side, 0 the other) the slope of the side stepped to counts. A negative optimum is a free way
    (nothing holds it: the optimiser stopped short); otherwise the limits with a non-zero multiplier of the
    program hold it."""
    names = list(grad)
    n, span = len(names), np.array([spans[k] for k in names])

    def split(g) -> np.ndarray:  # {variable: (left, right)} -> the row over (p, q)
        return np.concatenate([span * [g[k][1] for k in names], -span * [g[k][0] for k in names]])
    c = split(grad)
    sides = [(a, s) for a in active for s in ((1.0, -1.0) if a["kind"] == "equal" else  # neither way
                                               (1.0,) if a["kind"] == "upper" else (-1.0,))]
    rows = np.array([s * split({k: _sides(jacobian.get(a["name"], {}).get(k, 0.0)) for k in names})
                     for a, s in sides]).reshape(len(sides), 2 * n)
    active = [a for a, _ in sides]
    room = room or {}
    box = ([(0.0, 0.0) if on_bound.get(k) == "upper" else (0.0, room.get(k, (1.0, 1.0))[1]) for k in names]
           + [(0.0, 0.0) if on_bound.get(k) == "lower" else (0.0, room.get(k, (1.0, 1.0))[0]) for k in names])
    if not names or not (np.isfinite(c).all() and np.isfinite(rows).all()):  # a failed point: no first-order model
        return [], 0.0
    tol = 1e-9 * (float(np.abs(c).sum()) + float(np.abs(rows).sum()) + 1e-300)
    res = one_sided_descent(c, rows, box)
    if res is None:
        return [], 0.0
    if res.fun < -tol:
        return [], float(-res.fun)
    held = [a for a, m in zip(active, res.ineqlin.marginals if len(active) else []) if abs(m) > tol]
    return [a for i, a in enumerate(held) if all(a is not b for b in held[:i])], 0.0


def _num(v: float, scale: float | None = None) -> str:
    """4 significant digits; a margin below 1e-6 of its scale (the optimiser's feasibility
    tolerance) is shown as 0."""
    if scale is not None and abs(v) < 1e-6 * scale:
        return "0"
    return f"{v:.4g}"


def summary_lines(ans: Mapping[str, Any]) -> list[str]:
    """Short sentences: what holds the design (feasible) or what is violated and what blocks."""
    lines = []

    def u(s: str) -> str:
        return f" {s}" if s else ""

    def limit(e: Mapping[str, Any]) -> str:
        return f"{_limit(e)}{u(e['unit'])}"

    def monitored(e: Mapping[str, Any]) -> str:
        return " (monitored only)" if e.get("monitor") else ""

    for b in ans.get("outside_bounds", ()):
        lines.append(f"outside its bounds: {b['name']} = {b['value']:.6g}{u(b['unit'])}, "
                     f"{'below its lower' if b['kind'] == 'lower' else 'above its upper'} bound {b['bound']:g}"
                     f"{u(b['unit'])} by {_num(b['by'])}{u(b['unit'])} (the constraints below are valued there)")
    for e in ans["violated"]:
        if not np.isfinite(e["value"]):  # a failed point: no value to be short of the limit by, and its
            # Jacobian is NaN, so "no bound blocks it" would be a guess
            lines.append(f"no value: {limit(e)} (the point failed){monitored(e)}")
            continue
        lines.append(f"violated: {limit(e)} is {e['value']:.6g}{u(e['unit'])}, "
                     f"{'short' if e['value'] < e['limit'] else 'over'} by {_num(e['violation'])}{u(e['unit'])}"
                     + monitored(e))
        if "blocked_by" in e:
            if e["blocked_by"]:
                lines.append("  blocked by " + "; ".join(
                    f"{b['variable']} on its {b['bound']} bound ({b['rate']:.3g} {b['rate_unit']})"
                    for b in e["blocked_by"]))
            else:
                lines.append("  no design-variable bound blocks it")
            if e["conflicts_with"]:
                lines.append("  reducing it would break " + ", ".join(e["conflicts_with"]))
            if e.get("trades_with"):
                lines.append("  reducing it would worsen " + ", ".join(e["trades_with"]) + " (violated too)")
            if e.get("free_way") and e.get("free_way_reduction", np.inf) >= e["violation"]:
                lines.append("  a first-order step within the bounds removes it without worsening an active limit: "
                             "the optimiser stopped short")
            elif e.get("free_way"):  # a descent that the slopes say ends short of the limit: no retry's promise
                lines.append(f"  a first-order step within the bounds reduces it by at most "
                             f"{_num(e['free_way_reduction'])}{u(e['unit'])} without worsening an active limit, not to "
                             "its limit: the end is near a least violation; other start points (--starts N) may "
                             "still reach a feasible design")
    for e in ans["active_constraints"]:
        lines.append(f"active: {limit(e)}, margin {_num(e['margin'], e['scale'])}{u(e['unit'])}{monitored(e)}")
    for b in ans["bounds"]:
        lines.append(f"on its {b['kind']} bound: {b['name']} = {_num(b['value'])}{u(b['unit'])} "
                     f"(bound {b['bound']:g}{u(b['unit'])}, margin {_num(b['margin'], b['scale'])}{u(b['unit'])})")
    if not lines:
        lines.append("no constraint is active and no design variable is on a bound")
    return lines


def fd_jacobian(config: Any, design: Mapping[str, float], disciplines: Disciplines,
                names: list[str] | None = None, rel_step: float = 1e-6) -> dict[str, dict[str, tuple[float, float]]]:
    """(left, right) one-sided slopes d output / d design variable at ``design`` by finite differences,
    evaluated in process as ONE batch (the point and its stencil); a side whose step leaves the box takes
    the other side's slope. ``config``: the
    run's ``RunSettings``, or a resolved config.
    ``disciplines``: the run's discipline objects (a caller may wrap them, e.g. with a timeout), or a
    function building them (the engine does not read the application config)."""
    from bev_mdo.mdo.driver import _mda
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.mdo.settings import RunSettings

    ev = InProcessEvaluator(disciplines() if callable(disciplines) else disciplines)
    try:
        run = RunSettings.of(config, ev)
        problem = run.optimisation_problem()
        mda = _mda(run, ev, problem)
        x = np.array([float(design[n]) for n in problem.names])
        steps = []  # (variable, step): each side that stays in the box, else the one into it
        for j, (d, xi) in enumerate(zip(problem.design_variables, x)):
            h = rel_step * (d.upper - d.lower)
            inside = [s for s in (-h, h) if d.lower <= xi + s <= d.upper]
            steps += [(j, s) for s in inside or [-h if xi + h > d.upper else h]]
        pts = np.repeat(x[None, :], len(steps) + 1, axis=0)
        for i, (j, h) in enumerate(steps):
            pts[i + 1, j] += h
        inputs = {k: np.full(len(pts), float(v)) for k, v in problem.parameters.items()}
        inputs.update({n: pts[:, j] for j, n in enumerate(problem.names)})
        res = mda.run(inputs)
        outs = names or sorted({c.name for c in problem.constraints})
        jac = {}
        for o in outs:
            col = np.asarray(res.values[o], dtype=float)
            slopes = {}
            for i, (j, h) in enumerate(steps):
                slopes.setdefault(j, {})[h > 0] = float((col[i + 1] - col[0]) / h)
            jac[o] = {n: (slopes[j].get(False, slopes[j].get(True)), slopes[j].get(True, slopes[j].get(False)))
                      for j, n in enumerate(problem.names)}
        return jac
    finally:
        ev.close()


def answers_for(config: Any, design: Mapping[str, float], values: Mapping[str, float],
                disciplines: Disciplines, rel_tol: float = REL_TOL,
                units: Mapping[str, str] | None = None) -> dict[str, Any]:
    """``analyse`` for a run (its ``RunSettings``, or a resolved config); an infeasible end gets the
    Jacobian by ``fd_jacobian`` (in process, with ``disciplines``: a list, or a function building them,
    called only then); ``units``: {variable: unit} as the disciplines declare them (mdo/units.py
    ``run_units``)."""
    from bev_mdo.mdo.problem import Problem
    from bev_mdo.mdo.settings import RunSettings

    if isinstance(config, RunSettings):
        problem, tol = config.optimisation_problem(), float(config.optimizer.feasibility_tolerance)
    else:
        problem = Problem.from_config(config["problem"])
        tol = float((config.get("optimizer") or {}).get("feasibility_tolerance", FEASIBILITY_TOL))
    ans = analyse(problem, design, values, rel_tol=rel_tol, feas_tol=tol, units=units)
    if ans["violated"]:
        try:
            jac = fd_jacobian(config, design, disciplines=disciplines)
        except Exception as exc:  # a model that fails near the point: say so, keep the rest
            ans["jacobian_error"] = f"{type(exc).__name__}: {exc}"
        else:
            ans = analyse(problem, design, values, jacobian=jac, rel_tol=rel_tol, feas_tol=tol, units=units)
    return ans
