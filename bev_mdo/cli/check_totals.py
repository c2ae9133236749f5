"""``bev-mdo check-totals CONFIG [--formulation mdf|idf] [--at K=V,...] [--step H] [--json]``.

Compares the total derivatives of the objective and of every constraint (and, under IDF, of every
consistency equality) that the optimiser is given (the formulation's gradients: assembled from
the disciplines' partials, or its own finite differences, as ``optimizer.derivatives`` says) with
central finite differences of the whole formulation at one design, all finite-difference points
in ONE batch, in process or over ROS. The design variables default to their initial values;
under IDF the coupling variables start where one MDA of that design puts them. A total disagrees
when |total - fd| > atol + rtol * max(|total|, |fd|); a side whose point fails is left out (one-sided).
Exit status: 0 all agree, 1 some disagree, lack a difference or the point failed, 2 a user mistake.
"""
from __future__ import annotations

import sys

import numpy as np

from bev_mdo import jsontext


def register(subparsers) -> None:
    from bev_mdo.cli.flags import add_override_arguments, add_transport_arguments

    p = subparsers.add_parser("check-totals", description=__doc__.split("\n\n")[1])
    p.add_argument("config", help="run config YAML")
    p.add_argument("--formulation", choices=("mdf", "idf"), default=None, help="default: the config's")
    p.add_argument("--at", default="", metavar="K=V,...", help="design point (default: the initial values)")
    p.add_argument("--step", type=float, default=1e-6,
                   help="relative central-difference step: h = step * max(|x|, 1) (default 1e-6)")
    p.add_argument("--rtol", type=float, default=1e-4, help="relative tolerance (default 1e-4)")
    p.add_argument("--atol", type=float, default=1e-6, help="absolute tolerance (default 1e-6)")
    p.add_argument("--json", action="store_true", help="print JSON")
    add_transport_arguments(p)
    add_override_arguments(p)
    p.set_defaults(func=run)


def fd_stencil(x: np.ndarray, lower: np.ndarray, upper: np.ndarray, step: float) -> tuple[np.ndarray, ...]:
    """(rows (2n, n): x + h e_i then x - h e_i, denominators (n,), one-sided (n,): True where a bound within a
    step leaves one side out)."""
    h = step * np.maximum(np.abs(x), 1.0)
    up = np.where(x + h <= upper, h, 0.0)
    down = np.where(x - h >= lower, h, 0.0)
    eye = np.eye(len(x))
    return np.vstack([x + eye * up[:, None], x - eye * down[:, None]]), up + down, (up == 0.0) | (down == 0.0)


def check(form, x: np.ndarray, step: float = 1e-6, rtol: float = 1e-4, atol: float = 1e-6) -> dict:
    """The report (JSON-ready): one row per (function, variable) with the formulation's total, the
    finite difference and their errors. Functions: the objective (as the problem states it, not
    negated when maximised), each constraint output (physical units), each IDF consistency."""
    from bev_mdo.cli.check_partials import check_tolerances
    from bev_mdo.mdo.problem import check_resolved

    check_tolerances(step, rtol, atol)
    for j, name in enumerate(form.var_names):  # a point the scaled variables cannot hold was checked elsewhere
        check_resolved(name, float(x[j]), float(form.offset[j]), float(form.scale[j]))
    u = form.to_u(np.asarray(x, dtype=float))
    x = form.to_x(u)  # the point the gradient evaluates (scaling's round trip may move a coupling by an ulp)
    sign = -1.0 if form.problem.maximize else 1.0
    df, dg, dh = form.gradients(u)  # d/du, u = (x - offset) / scale
    ok, why = form.status(x)
    if not ok:  # a failed point, not a user mistake: exit 1 (ModelFailed)
        from bev_mdo.api.errors import ModelFailed

        raise ModelFailed(f"the analysis of the design failed: {why.splitlines()[0]}")
    rows_x, denom, sided = fd_stencil(x, form.lower, form.upper, step)
    rows_x = np.vstack([rows_x, x])  # the point itself last: the other side of a difference whose one side failed
    f, g, h = form.evaluate_batch(rows_x)
    status = [form.status(r) for r in rows_x[:-1]]
    failed = np.array([not ok for ok, _ in status])
    bad = [why for ok, why in status if not ok]
    n = form.n
    # physical functions: objective, constraint outputs y (g = sign (y - bound) / scale), consistencies;
    # differences of y itself (g rounds y to eps |bound|: a bound far from y would cost digits)
    _, gsign, gscale = form.problem.g_terms()
    names = [form.problem.objective] + [lab for lab in form.ineq_labels] + list(form.eq_labels)
    totals = np.vstack([sign * df[None, :], (gsign * gscale)[:, None] * dg, dh]) / form.scale[None, :]
    vals = np.column_stack([sign * f, form.constraint_outputs(rows_x), h])
    # a failed side is left out (its values are the failure's penalty, not the function's): one-sided from the point
    up, down = np.diag(rows_x[:n]) - x, x - np.diag(rows_x[n:2 * n])
    plus, minus = np.where(failed[:n, None], vals[-1], vals[:n]), np.where(failed[n:, None], vals[-1], vals[n:2 * n])
    denom = np.where(failed[:n], 0.0, up) + np.where(failed[n:], 0.0, down)
    with np.errstate(divide="ignore", invalid="ignore"):
        fd = np.where(denom[:, None] > 0, (plus - minus) / np.where(denom > 0, denom, 1.0)[:, None], np.nan).T
    one_sided = [v for v, s, a, b in zip(form.var_names, sided, failed[:n], failed[n:]) if s or a != b]
    report = {"formulation": form.name, "derivatives": form.derivatives, "point": dict(zip(form.var_names, x.tolist())),
              "step": step, "rtol": rtol, "atol": atol, "one_sided": one_sided, "rows": [], "ok": True,
              "error": f"{len(bad)} finite-difference points failed (left out): {bad[0].splitlines()[0]}" if bad else ""}
    for i, fn in enumerate(names):
        for j, v in enumerate(form.var_names):
            a, b = float(totals[i, j]) + 0.0, float(fd[i, j]) + 0.0  # no -0 in the table; NaN: both sides failed
            err = abs(a - b)
            rel = err / max(abs(a), abs(b)) if max(abs(a), abs(b)) > 0 else 0.0
            ok = bool(err <= atol + rtol * max(abs(a), abs(b)))
            report["rows"].append({"of": fn, "wrt": v, "total": a, "fd": b, "abs_error": err, "rel_error": rel, "ok": ok})
            report["ok"] &= ok
    return report


def _point(form, problem, text: str) -> np.ndarray:
    from bev_mdo.cli.check_partials import _point as design_point

    design = design_point(problem, text)
    x = np.array(form.x0, dtype=float)
    for j, name in enumerate(problem.names):
        x[j] = design[name]
    if form.name == "idf" and text:  # the couplings where one MDA of this design puts them
        res = form.mda.run({**{k: [v] for k, v in design.items()}, **{k: [v] for k, v in problem.parameters.items()}})
        if res.ok[0]:
            for k, c in enumerate(form.couplings):
                x[len(problem.names) + k] = res.values[c][0]
        else:  # checked where the run starts them instead, which the header shows: said, not silent
            print(f"bev-mdo check-totals: note: the MDA of this design failed ({res.messages[0]}); the couplings keep "
                  "the values a run starts from (shown in the header), not values consistent at this design",
                  file=sys.stderr)
    return x


def run(args) -> int:
    from bev_mdo.api.evaluate import declared_units, note_outside_bounds
    from bev_mdo.api.transport import Evaluating
    from bev_mdo.cli import flags
    from bev_mdo.cli.check_partials import _per, check_tolerances
    from bev_mdo.mdo.driver import build_formulation

    config = flags.load_config(args)
    check_tolerances(args.step, args.rtol, args.atol)  # before any node starts
    with Evaluating(config, args, node_name="bev_mdo_check_totals") as ev:
        form = build_formulation(config.settings, ev, args.formulation)
        x = _point(form, form.problem, args.at)
        note_outside_bounds(form.problem, dict(zip(form.problem.names, x.tolist())), "bev-mdo check-totals")
        rep = check(form, x, args.step, args.rtol, args.atol)
    units = declared_units(config, form.var_names)  # a model parameter as a design variable: its unit too
    for r in rep["rows"]:  # an IDF consistency is normalised by its coupling's scale: 1 per unit of the variable
        r["unit"] = _per(units, "" if r["of"].endswith(" consistency") else r["of"].split()[0], r["wrt"]).strip() or "1"
    if args.json:
        print(jsontext.dumps(rep))
    else:
        print_table(rep)
    return 0 if rep["ok"] else 1


def print_table(rep: dict) -> None:
    print(f"total derivatives ({rep['formulation'].upper()}, {rep['derivatives']}) at "
          f"{', '.join(f'{k}={v:g}' for k, v in rep['point'].items())}")
    print(f"against central differences (step {rep['step']:g}; rtol {rep['rtol']:g}, atol {rep['atol']:g})"
          + (f"; one-sided for {', '.join(rep['one_sided'])}: a bound or a failed point within a step"
             if rep.get("one_sided") else ""))
    wf = max(10, *(len(r["of"]) for r in rep["rows"])) + 1
    wv = max(8, *(len(r["wrt"]) for r in rep["rows"])) + 1
    wu = max(4, *(len(r.get("unit", "")) for r in rep["rows"])) + 1
    print(f" {'of':<{wf}} {'wrt':<{wv}} {'unit':<{wu}} {'total':>14} {'fd':>14} {'abs err':>10} {'rel err':>10}  status")
    for r in rep["rows"]:
        tiny = max(abs(r["total"]), abs(r["fd"])) <= rep["atol"]  # both within atol of 0: no relative error to speak of
        print(f" {r['of']:<{wf}} {r['wrt']:<{wv}} {r.get('unit', ''):<{wu}} {r['total']:>14.8g} {r['fd']:>14.8g} "
              f"{r['abs_error']:>10.3g} "
              f"{'-' if tiny else format(r['rel_error'], '.3g'):>10}  "
              f"{'ok' if r['ok'] else 'DISAGREE' if r['fd'] == r['fd'] else 'no fd: no side left'}")
    if rep["error"]:
        print(rep["error"])
    print(summary(rep))


def summary(rep: dict) -> str:
    """The last line: the largest relative error among the differences above ``atol`` (between two values
    within atol of zero, 0 against 8e-11, a relative error of 1 says nothing), and the verdict."""
    beyond = [r for r in rep["rows"] if r["abs_error"] > rep["atol"]]
    worst = max(beyond, key=lambda r: r["rel_error"]) if beyond else None
    missing = sum(r["fd"] != r["fd"] for r in rep["rows"])  # NaN: its two sides failed, or one failed at a bound
    return ((f"largest relative error {worst['rel_error']:.3g} (d {worst['of']} / d {worst['wrt']}) among the "
             f"differences above atol {rep['atol']:g}; " if worst else f"every difference is within atol {rep['atol']:g}; ")
            + (f"{missing} total{'s have' if missing > 1 else ' has'} no finite difference (a failed point on one side, "
               "a failed point or a bound on the other); " if missing else "")
            + ("all totals agree with finite differences" if rep["ok"] else
               "some totals disagree" if any(not r["ok"] and r["fd"] == r["fd"] for r in rep["rows"]) else
               "none disagrees"))
