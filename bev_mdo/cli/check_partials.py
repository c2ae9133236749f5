"""``bev-mdo check-partials CONFIG [--at K=V,...] [--rtol R] [--atol A] [--step H] [--json]``.

Compares every discipline's analytic partial derivatives (``compute_partials``) with central
finite differences of that discipline alone, at the inputs it sees in the multidisciplinary
analysis of one design (design variables default to their initial values; a vector element is
``z[0]=1``, a whole vector ``z=1``). An entry disagrees when |analytic - fd| > atol + rtol *
max(|analytic|, |fd|). Prints one table row per discipline and one line per disagreeing entry.
Exit status: 0 every partial agrees, 1 some partial disagrees (or has the wrong shape), 2 user
mistake. Disciplines without partials are listed as "finite differences" (nothing to check).
"""
from __future__ import annotations

import math

import numpy as np

from bev_mdo import jsontext


def register(subparsers) -> None:
    p = subparsers.add_parser("check-partials")
    p.add_argument("config", help="run config YAML")
    p.add_argument("--at", default="", metavar="K=V,...",
                   help="design point (design variables default to their initial values; z[0]=1 or z=1 for a vector)")
    p.add_argument("--rtol", type=float, default=1e-4, help="relative tolerance (default 1e-4)")
    p.add_argument("--atol", type=float, default=1e-6, help="absolute tolerance (default 1e-6)")
    p.add_argument("--step", type=float, default=1e-6,
                   help="relative central-difference step: h = step * max(|input|, 1) (default 1e-6)")
    p.add_argument("--discipline", default="", metavar="NAMES", help="comma-separated disciplines (default: all)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def _point(problem, text: str) -> dict[str, float]:
    from bev_mdo.cli.flags import parse_assignments

    point = dict(zip(problem.names, problem.x0().tolist()))
    for k, v in parse_assignments(text, "--at").items():
        if k in point:
            point[k] = v
        elif k in problem.shapes and f"{k}[0]" in point:
            for i in range(problem.shapes[k]):
                point[f"{k}[{i}]"] = v
        else:
            raise ValueError(f"--at names {k!r}, which is not a design variable; design variables: {problem.names}")
    return point


def check_tolerances(step: float, rtol: float, atol: float) -> None:
    """ValueError naming the first of ``--step`` (in (0, 0.1)), ``--rtol`` and ``--atol`` (>= 0) that is out of
    its range, with its value (check-partials, check-totals)."""
    for flag, v, ok, allowed in (("--step", step, 0 < step < 0.1, "in (0, 0.1)"),  # (inf passed every check)
                                 ("--rtol", rtol, 0 <= rtol < math.inf, ">= 0, finite"),
                                 ("--atol", atol, 0 <= atol < math.inf, ">= 0, finite")):
        if not ok:  # NaN too
            raise ValueError(f"{flag} {v:g}: must be {allowed}")


def check(config, at: str = "", rtol: float = 1e-4, atol: float = 1e-6, step: float = 1e-6,
          only: list[str] | None = None) -> dict:
    """The report of ``bev-mdo check-partials`` (JSON-ready)."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.derivatives import compare_partials, fd_partials
    from bev_mdo.mdo.discipline import run_discipline
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.mdo.vectors import ShapeError, has_partials

    check_tolerances(step, rtol, atol)
    config = RunConfig.of(config)
    discs = {d.name: d for d in config.timed_disciplines()}
    unknown = [n for n in (only or []) if n not in discs]
    if unknown:
        raise ValueError(f"--discipline names {unknown}; the config has {sorted(discs)}")
    ev = InProcessEvaluator(discs.values())
    form = build_formulation(config.settings, ev, "mdf")
    problem, mda = form.problem, form.mda
    point = _point(problem, at)
    inputs = {k: np.array([v]) for k, v in {**problem.parameters, **point}.items()}
    res = mda.run(inputs)
    if not res.ok[0]:
        raise ValueError(f"the analysis of the point failed: {res.messages[0]}")
    values = {k: v[:1] for k, v in res.values.items()}
    report = {"design": point, "rtol": rtol, "atol": atol, "step": step, "disciplines": [], "ok": True}
    for name in only or list(mda.specs):
        d = discs[name]
        entry = {"discipline": name, "partials": "analytic" if has_partials(d) else "finite differences",
                 "entries": 0, "max_rel_error": 0.0, "max_abs_error": 0.0, "mismatches": [], "error": ""}
        report["disciplines"].append(entry)
        if not has_partials(d):
            continue
        spec = mda.specs[name]
        cols = {v: values[v] for v in spec.inputs}
        cols.update({p: values[p] for p in spec.parameters if p in values})
        try:
            got = run_discipline(d, cols, partials=True)
        except ShapeError as exc:
            entry["error"] = str(exc)
            continue
        if not got.ok.all():
            entry["error"] = got.error or "the discipline failed at this point"
            continue
        analytic = got.extra.get("partials", {})
        # central differences around the discipline's own outputs at these inputs
        base = {**values, **got.outputs}
        fd, failed = fd_partials(ev, mda.specs, [name], base, 1, step, central=True)
        rows = compare_partials(analytic, fd.get(name, {}), rtol, atol)
        entry["entries"] = len(rows)
        entry["max_rel_error"] = max((r["rel_error"] for r in rows), default=0.0)
        entry["max_abs_error"] = max((r["abs_error"] for r in rows), default=0.0)
        entry["mismatches"] = [r for r in rows if not r["ok"]]
        if failed:
            entry["error"] = f"{sum(failed.values())} finite-difference points failed"
    report["ok"] = not any(e["error"] or e["mismatches"] for e in report["disciplines"])
    return report


def run(args) -> int:
    from bev_mdo.api.evaluate import note_outside_bounds
    from bev_mdo.config import RunConfig

    config = RunConfig.load(args.config)
    only = [s.strip() for s in args.discipline.split(",") if s.strip()] or None
    check_tolerances(args.step, args.rtol, args.atol)  # before the note on the point
    note_outside_bounds(config.problem, _point(config.problem, args.at), "bev-mdo check-partials")
    rep = check(config, args.at, args.rtol, args.atol, args.step, only)
    from bev_mdo.api.evaluate import declared_units

    units = declared_units(config)
    if args.json:
        print(jsontext.dumps(rep))
        return 0 if rep["ok"] else 1
    print(f"partials at {', '.join(f'{k}={v:g}' for k, v in rep['design'].items())} "
          f"(central differences, step {args.step:g}; rtol {args.rtol:g}, atol {args.atol:g})")
    print(f" {'discipline':<22} {'partials':<19} {'entries':>7} {'max rel err':>12} {'max abs err':>12}  status")
    for e in rep["disciplines"]:
        if e["partials"] != "analytic":
            print(f" {e['discipline']:<22} {e['partials']:<19} {'-':>7} {'-':>12} {'-':>12}  -")
            continue
        status = "ERROR" if e["error"] else ("DISAGREE" if e["mismatches"] else "ok")
        print(f" {e['discipline']:<22} {e['partials']:<19} {e['entries']:>7} {e['max_rel_error']:>12.3g} "
              f"{e['max_abs_error']:>12.3g}  {status}")
    for e in rep["disciplines"]:
        if e["error"]:
            print(f"{e['discipline']}: {e['error']}")
        for r in e["mismatches"]:  # in the run's units, which a partial given per another unit was converted to
            per = _per(units, r["output"], r["input"])
            print(f"{e['discipline']}: d{r['output']}/d{r['input']} analytic {r['analytic']:.8g} but finite "
                  f"differences {r['fd']:.8g}{per} (rel error {r['rel_error']:.3g})")
    checked = [e["discipline"] for e in rep["disciplines"] if e["partials"] == "analytic"]
    if any(e["mismatches"] for e in rep["disciplines"]):
        print("(each partial in the run's units, per unit of the input as its producer declares it)")
    print("some analytic partials disagree with finite differences" if not rep["ok"] else
          "all analytic partials agree with finite differences" if checked else
          "nothing checked: no discipline checked here declares analytic partials (their derivatives are finite "
          "differences of the whole analysis)")
    return 0 if rep["ok"] else 1


def _per(units: dict, output: str, inp: str) -> str:
    """' kN per m' for d output / d input in their declared units ('' where neither has one)."""
    from bev_mdo.mdo.units import unit_of

    top, bottom = (unit_of(n, units, inline=True) for n in (output, inp))
    return f" {top or '1'} per {bottom}" if bottom else (f" {top}" if top else "")
