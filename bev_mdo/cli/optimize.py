"""`bev-mdo optimize CONFIG`: the main job.

Over ROS (default) it starts one process per discipline and a recorder, runs the
coordinator in this process, shows progress, prints the optimum (beside the config's
``problem.baseline`` when it names one, e.g. the Nissan Leaf in config/leaf_nedc.yaml),
writes the bag and shuts every process down (also on Ctrl-C).
`--transport inprocess` runs the same engine with no ROS at all.

Every run ends with a first-order check of its result (bev_mdo/mdo/first_order.py); the verdict
follows from it. Exit status: 0 an optimum (first-order conditions hold), or with ``--fixed-budget``
any feasible end; 1 the run finished infeasible; 2 a user mistake; 3 the recorder failed; 4 a
discipline stopped answering; 5 feasible but not a verified optimum (stopped before convergence, or
no progress from the start point); 7 an unexpected error stopped the run (one line names it). A
finished run always prints its result (with ``--json``, the JSON on stdout), whatever the baseline does.
"""
from __future__ import annotations

import sys

from bev_mdo import interrupts, jsontext


def register(sub) -> None:
    from bev_mdo.cli.flags import seed

    p = sub.add_parser("optimize", description="Optimise the config's problem. Over ROS every discipline runs as its own "
                                   "node (localhost discovery, the config's domain id), by default in this "
                                   "command's process (--compose none: a process each).")
    p.add_argument("config", help="run config YAML, e.g. config/leaf_nedc.yaml")
    p.add_argument("--formulation", choices=["mdf", "idf"], default=None, help="default: the config's")
    p.add_argument("--optimizer", default=None,
                   help="SLSQP | trust-constr | COBYQA | COBYLA | differential_evolution | chebyshev-pairwise")
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.add_argument("--bag", default=None, help="bag directory to write (default: bags/<config name>_<time>_<run>)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--starts", type=int, default=1, metavar="N",
                   help="optimise from N start points (a Latin hypercube over the bounds, --seed) and report the "
                        "best and how many starts reached it (default 1: the config's initial design)")
    p.add_argument("--seed", type=seed, default=0, help="seed of the --starts sample and of differential_evolution "
                   "when optimizer.options give it no seed (default 0)")
    p.add_argument("--fixed-budget", action="store_true",
                   help="the optimiser's limits (e.g. optimizer.options.maxiter) are the budget: a feasible end "
                        "exits 0 even when it is not a verified optimum (the verdict still says what it is)")
    from bev_mdo.cli.flags import add_layout_arguments, add_override_arguments, add_transport_arguments

    add_layout_arguments(p)
    add_transport_arguments(p, attach=False, record="do not record the run (over ROS the node logs and the per-run "
                            "key go in a temporary directory, removed after; with --bag, logs/ is kept there)")
    add_override_arguments(p)
    p.set_defaults(func=run)


def _progress(quiet: bool, to_stderr: bool):
    from bev_mdo.mdo.formulations import FAIL_OBJECTIVE

    out = sys.stderr if to_stderr else sys.stdout

    def show(rec: dict) -> None:
        if quiet:
            return
        idf = rec.get("formulation") == "idf"  # IDF runs no MDA: count discipline evaluations
        n = sum(rec.get("discipline_evaluations", {}).values()) if idf else rec.get("mda_evaluations", 0)
        rate = n / max(rec.get("wall_time_s", 0.0), 1e-9)
        # a design whose evaluation failed has no objective value (NaN in its record)
        objective = (f"{rec['objective']:12.6f}" if abs(rec["objective"]) < FAIL_OBJECTIVE  # False for NaN
                     else f"{'not evaluated':>12s}")
        start = f"start {rec['start'][0] + 1}/{rec['start'][1]}  " if rec.get("start") else ""  # a multi-start's
        # a multi-start's: the start's own iteration (the record's is the run's count over interleaved starts)
        print(f"{start}iter {rec.get('start_iteration', rec['iteration']):4d}  {rec['objective_name']} {objective}  "
              f"max violation {rec['max_violation']:9.3g}  {'feasible  ' if rec['feasible'] else 'infeasible'}"
              f"{': cannot follow the cycle' if rec.get('cannot_follow') else ''}"  # the run's design_check
              f"  {rate:9.0f} {'discipline' if idf else 'MDA'} evals/s", file=out, flush=True)

    return show


def set_line(source: dict) -> str:
    """A parameter set as a run names it: 'epa2022_quasi_static', or 'mine (/x/mine.yaml, sha256 1a2b..., fitted
    2026-12-07)' for one given as a file."""
    more = [source[k] for k in ("file",) if source.get(k)] + [f"{k} {source[k]}" for k in ("sha256", "fitted")
                                                                if source.get(k)]
    return source["name"] + (f" ({', '.join(more)})" if more else "")


def own_message(message: str) -> str:
    """The optimiser's own message: ``message`` up to the first '; ' that the driver appends (the result's
    iteration, a failed final point), not one inside its parentheses (SLSQP's restarts, '(restart 1 after: ...;
    restart 2 after: ...)')."""
    depth = 0
    for i, c in enumerate(message):
        depth += (c == "(") - (c == ")")
        if depth == 0 and message.startswith("; ", i):
            return message[:i]
    return message


def _table(result: dict, baseline: dict | None, out, units: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    sense = "maximised" if result.get("maximize") else "minimised"
    title = f"Result ({result['formulation'].upper()}, {result['optimizer']}; {result['objective_name']} {sense})"
    if baseline is not None:
        title += f" beside {baseline['name']}"
    t = Table(title=title)
    t.add_column("quantity")
    t.add_column("result", justify="right")
    if baseline is not None:
        t.add_column(baseline["name"], justify="right")

    def row(k, v, ref):
        t.add_row(k, f"{v:.6g}", *([f"{ref:.6g}"] if baseline is not None else []))

    bd, bo = (baseline or {}).get("design", {}), (baseline or {}).get("outputs", {})
    for k, v in result["design"].items():
        row(k, v, bd.get(k, float("nan")))
    for k, v in result["outputs"].items():
        if k not in result["design"]:
            row(k, v, bo.get(k, float("nan")))
    t.add_row("feasible", str(result["feasible"]), *([str(baseline["feasible"])] if baseline is not None else []))
    Console(file=out).print(t)
    if baseline is not None:  # its failure, and what its column does not show (outside its bounds, a parameter set)
        for line in ([baseline["error"]] if baseline.get("error") else []) + list(baseline.get("notes", ())):
            print(f"baseline {baseline['name']}: {line}", file=out)
    for line in result.get("notes", ()):
        print(f"result: note: {line}", file=out)
    if result.get("error"):
        print(f"the result point failed: {result['error']}", file=out)
    elif result.get("stopped"):  # a discipline stopped answering: the run stopped the optimiser
        print(f"the run {result['stopped']}", file=out)
    elif not result.get("optimizer_success", True):  # e.g. SLSQP's iteration limit
        print(f"{result['optimizer']} says: {own_message(result['message'])}", file=out)
    if result.get("projected"):  # a result just outside its bounds, projected onto them
        from bev_mdo.mdo.driver import projected_line

        print(f"result: {projected_line(result['projected'])}", file=out)
    if not result.get("last_iterate", True):
        print(f"result: iteration {result['result_iteration']}, the best feasible point seen "
              f"(not the optimiser's last iterate, iteration {result['iterations']})", file=out)
    if result.get("fd_failures"):  # a derivative-free optimiser's are the first-order check's, not its own
        from bev_mdo.mdo.optimizers import GRADIENT_BASED

        own = result["optimizer"] in GRADIENT_BASED
        print(f"warning: {result['fd_failures']} finite-difference point(s) failed and gave zero derivatives"
              + ("; the optimiser may have stopped early" if own else " to the first-order check (not to "
                 f"{result['optimizer']}, which uses none)") + " (see discipline_errors)", file=out)
    ms = result.get("multistart")  # its evaluations are summed over the starts; the iterations are the best start's
    over = f" (start {ms['best_start'] + 1}'s; {sum(r['iterations'] for r in ms['results'])} over {ms['starts']} starts)" if ms else ""
    print(f"iterations {result['iterations']}{over}, MDA evaluations {result['mda_evaluations']}, "
          f"evaluations per discipline {result['discipline_evaluations']}", file=out)
    print(f"optimiser wall time {result['wall_time_s']:.3f} s (first evaluation to result)", file=out)
    _verdict(result, out, units)


def _verdict(result: dict, out, units: dict) -> None:
    """The first-order verdict and the active set with its multipliers (physical margins beside)."""
    from bev_mdo.mdo.first_order import note_lines, verdict_line
    from bev_mdo.mdo.units import unit_of

    fo = result["first_order"]
    cost = fo["cost"]
    print(f"verdict: {verdict_line(fo)}", file=out)
    for line in note_lines(fo, result.get("optimizer", "the optimiser"), bool(result.get("optimizer_success")),
                           result.get("ended")):
        print(f"note: {line}", file=out)
    if result.get("multistart"):
        from bev_mdo.mdo.multistart import summary_line

        print(summary_line(result["multistart"]), file=out)
    kink = fo.get("kink_points", 0)  # driver.end_point_check: its steps either side of the point, for a kink
    free = fo.get("free_points", 0)  # and along a variable whose gradient is zero, for one nothing holds
    why = (["the optimiser's last gradient reused"] if cost["points"] == kink + free else
           ["central differences confirmed the analytic derivatives"] if fo.get("derivatives_confirmed") else
           [f"{cost['points'] - kink - free} for the gradient"]) + ([f"{kink} to look for a kink"] if kink else []) + (
        [f"{free} along a variable with a zero gradient"] if free else [])
    print(f"first-order check: {cost['points']} extra point{'' if cost['points'] == 1 else 's'} in "
          f"{cost['wall_time_s']:.3f} s ({'; '.join(why)})", file=out)
    if fo["verdict"] == "infeasible":
        return  # the answers below say what is violated and what blocks it

    def u(name: str) -> str:  # " kW", or "" for a quantity without a unit
        return f" {unit_of(name, units, inline=True)}" if unit_of(name, units, inline=True) else ""

    obj = result.get("objective_name") or ""

    optimum = fo["verdict"] == "optimum"  # elsewhere the multipliers are a least-squares fit, no rate of an optimum

    def rate(name: str, d: float | None) -> str:  # " (-0.1492 Wh/km per s raised)": the multiplier's meaning
        return "" if d is None or not optimum else \
            f" ({d:.4g}{u(obj)} per {unit_of(name, units, inline=True) or 'unit'} raised)"

    lines, held = [], []  # held: [name, label, multiplier, rate]; an equality's two rows (>=, <=) as one, name == value
    for c in fo["active_constraints"]:
        name = c["name"].split(" ")[0]
        con = result["constraints"].get(name, {})
        d = c.get("d_objective_d_limit")
        if con.get("lower") is not None and con["lower"] == con.get("upper"):
            if held and held[-1][0] == name:  # its <= row: the equality's multiplier is the net one
                held[-1][2] = c["multiplier"] - held[-1][2]
                held[-1][3] = None if d is None or held[-1][3] is None else held[-1][3] + d  # both rows' limit moves
                continue
            held.append([name, f"{name} == {con['lower']:g}", c["multiplier"], d])
        else:
            held.append([name, c["name"], c["multiplier"], d])
    for name, label, multiplier, d in held:
        con = result["constraints"].get(name, {})
        margin, limit = con.get("margin", float("nan")), con.get("upper", con.get("lower")) or 0.0
        shown = "0" if abs(margin) <= 1e-6 * max(abs(limit), 1.0) else f"{margin:.3g}"  # below the noise: 0
        lines.append(f"active: {label}{u(name)}, margin {shown}{u(name)}, multiplier {multiplier + 0.0:.4g}{rate(name, d)}")
    for b in fo["active_bounds"]:
        v = {**result.get("outputs", {}), **result["design"]}.get(b["name"], float("nan"))  # IDF's couplings too
        v = b.get("bound", v) if abs(v - b.get("bound", v)) <= 1e-9 * max(1.0, abs(v)) else v  # 4.6e-13 on 0: 0
        lines.append(f"on its {b['kind']} bound: {b['name']} = {v:.6g}{u(b['name'])}, multiplier "
                     f"{b['multiplier'] + 0.0:.4g}{rate(b['name'], b.get('d_objective_d_limit'))}")
    for e in fo["equalities"]:
        lines.append(f"consistency: {e['name']}, residual {e['value']:.3g}, multiplier {e['multiplier'] + 0.0:.4g}")  # (-0.0 + 0.0 is 0.0)
    print(f"what holds the result (multipliers per unit of the scaled variables and normalised constraints"
          + (f"; in brackets, the change of the optimum's {obj} per unit the limit or bound is raised):" if optimum
             else "):")
          if lines else "no constraint is active and no variable is on a bound", file=out)
    for line in lines:
        print(f"  {line}", file=out)


class _Printing:
    """The stream the result is written to; its first write tells a signal's line that the result is being
    printed (interrupts.printing): one taken before, e.g. while rich is imported, came before it was printed."""

    def __init__(self, stream):
        self.stream = stream

    def write(self, text: str) -> int:
        if text:  # rich writes its buffer, empty, when the signal cut its rendering short
            interrupts.printing()
        return self.stream.write(text)

    def __getattr__(self, name: str):  # flush, isatty, fileno, encoding: rich's Console reads them
        return getattr(self.stream, name)


def run(args) -> int:
    from bev_mdo.cli import flags

    return run_job(flags.load_config(args), args)


def run_job(config: dict, args, x0: dict | None = None) -> int:
    """Run one optimisation of a resolved config as the CLI options say (x0 overrides the start),
    print it and return the exit status."""
    from bev_mdo.api import optimize

    opts = optimize.OptimizeOptions.of(args)
    opts.progress_to_stderr = bool(args.json)
    doc = optimize.run(config, opts, _progress(args.quiet, args.json), x0)
    out = _Printing(sys.stderr if args.json else sys.stdout)
    if args.json:
        print(jsontext.dumps(doc), file=_Printing(sys.stdout))
    else:
        from bev_mdo.api.evaluate import declared_units

        result = {k: v for k, v in doc.items() if k != "baseline"}
        _table(result, doc["baseline"], out, declared_units(config))
        if doc.get("parameter_set"):
            print(f"parameter set: {set_line(doc['parameter_set'])}", file=out)
        failed = (result.get("first_order") or {}).get("point_failed")  # the verdict line says why: no value
        if not doc["feasible"] and not failed:  # a feasible end printed the first-order check's active set instead
            ans = result["active"]
            short = (result.get("first_order") or {}).get("cannot_follow") or []  # the motor, not a constraint
            print("why the end point is infeasible:", *[f"  {line}" for line in [*short, *ans["lines"]]], sep="\n",
                  file=out)
            if ans.get("jacobian_error"):
                print(f"  (no blocking analysis: {ans['jacobian_error']})", file=out)
        keys = list(doc)
        for k in keys[keys.index("baseline") + 1:]:  # the transport's figures follow the result and baseline
            print(f"{k}: {doc[k]}" if k != "run_time_s" else f"run time {doc[k]:.3f} s (config loaded to this line: "
                  "start-up, optimisation, baseline, answers, shut-down)", file=out)
    lost = doc.get("unresponsive_disciplines")
    if lost:  # its later evaluations would all fail: the run stopped the optimiser (driver.run_until_lost)
        print(f"warning: {', '.join(lost)} stopped answering during the run (no answer within ros.timeout_s x "
              "(ros.retries + 1)); the optimiser was stopped there (every later evaluation of it would fail), so the "
              "result is the best point evaluated before that, not an optimum", file=sys.stderr)
    if doc.get("recorder_failed"):
        print(f"warning: {doc['recorder_failed']}", file=sys.stderr)
    from bev_mdo.mdo.first_order import exit_status

    return exit_status(doc, opts.fixed_budget)
