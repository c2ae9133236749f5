"""``bev-mdo sweep`` and ``bev-mdo compare``: many designs as one batch.

``sweep CONFIG --doe lhs|sobol|halton|full --samples N --seed S`` draws N designs over the design
variables' bounds (scipy.stats.qmc; ``full``: N levels per variable); ``--vary motor_kw=40:120:9
gear_ratio=6:10:5`` evaluates a full-factorial grid of given values (``lo:hi:n`` is n evenly spaced
values, ``a,b,c`` a list); ``--list FILE.csv`` the designs listed in a CSV (a header of names).
All designs are ONE batch of multidisciplinary analyses, through the config's discipline nodes
started for the command (default), the nodes already running (``--attach``) or in process
(``--transport inprocess``), written to ``sweep.csv`` (every design variable, every
output, each constraint's margin, feasible, ok), one PNG per output and a bag (``bag/``, one
record per design: ``history``/``report`` read it; written as soon as the batch is done, so a sweep
stopped before that has no bag). Variables not varied keep their initial value
(or ``--set`` values).

``compare CONFIG --design k=v,... --design k=v,...`` prints two or more designs side by side
with every output, constraint margin and the difference of each from the first design.
"""
from __future__ import annotations

import contextlib
import csv
import itertools
import math
import os
import sys
from pathlib import Path

import numpy as np

from bev_mdo import jsontext
from bev_mdo.api.errors import InputError
from bev_mdo.api.evaluate import batch as evaluate_batch  # one batch of MDAs over the transport args choose
from bev_mdo.figures import colormap, styled, subplots


def register(sub) -> None:
    from bev_mdo.api.doe import METHODS
    from bev_mdo.cli.flags import add_override_arguments, add_transport_arguments, seed

    p = sub.add_parser("sweep", description=__doc__.split("\n\n")[1])
    p.add_argument("config", help="run config YAML")
    p.add_argument("--doe", choices=METHODS, default=None,
                   help="sample the design variables' bounds: Latin hypercube, Sobol', Halton or full factorial")
    p.add_argument("--samples", type=int, default=None,
                   help="--doe: number of designs (full: levels per variable; default 64)")
    p.add_argument("--seed", type=seed, default=None, help="--doe: random seed (lhs, sobol, halton; default 1)")
    p.add_argument("--vary", nargs="+", action="extend", default=[], metavar="NAME=LO:HI:N",
                   help="a grid: a design variable (or model parameter) and its values: lo:hi:n or a,b,c")
    p.add_argument("--list", dest="list_csv", metavar="FILE.csv", help="evaluate the designs listed in this CSV")
    p.add_argument("--set", dest="fixed", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                   help="fixed values for variables not varied (default: their initial value)")
    p.add_argument("--out", default="sweep", help="output directory (default ./sweep)")
    p.add_argument("--no-plots", action="store_true")
    add_transport_arguments(p, record="do not write the bag (OUT/bag)")
    add_override_arguments(p)
    p.set_defaults(func=run)
    c = sub.add_parser("compare", description=__doc__.split("\n\n")[2])
    c.add_argument("config", help="run config YAML")
    c.add_argument("--design", action="append", default=[], metavar="k=v,...", required=True,
                   help="one design (repeat); variables not given take their initial value")
    c.add_argument("--json", action="store_true")
    add_transport_arguments(c)
    c.set_defaults(func=run_compare)


def parse_vary(items: list[str]) -> dict[str, np.ndarray]:
    from bev_mdo.api.overrides import no_underscore

    out = {}
    for item in items:
        name, sep, spec = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise InputError(f"--vary {item!r} must be NAME=LO:HI:N or NAME=A,B,C")
        no_underscore(spec, f"--vary {item!r}")  # float() and int() read 1_00 as 100
        try:
            if ":" in spec:
                lo, hi, n = spec.split(":")  # a ValueError unless it has three parts
                if (bad := next((t for t in (lo, hi) if not math.isfinite(float(t))), None)) is not None:
                    raise InputError(f"{name}={bad.strip()}: a design value must be a finite number")  # (linspace:
                lo, hi, n = float(lo), float(hi), int(n)  # a RuntimeWarning, and 1e400 said as nan)
                if n < 1:
                    raise ValueError
                if n == 1 and lo != hi:  # linspace gives LO alone: HI was dropped without a word
                    raise InputError(f"--vary {item!r}: one value between {lo:g} and {hi:g}; give N >= 2, or LO:LO:1")
                if n > MAX_SWEEP_POINTS:
                    raise InputError(f"--vary {item!r}: {n} values; a sweep holds at most {MAX_SWEEP_POINTS} designs")
                vals = np.linspace(lo, hi, n)
            else:
                vals = np.array([float(v) for v in spec.split(",") if v.strip()])
            if not np.isfinite(vals).all():  # named as typed: 1e400 was said as inf
                bad = next(t for t in spec.split(",") if t.strip() and not math.isfinite(float(t)))
                raise InputError(f"{name}={bad.strip()}: a design value must be a finite number")
        except InputError:
            raise
        except ValueError:
            raise InputError(f"--vary {item!r}: values must be LO:HI:N (N >= 1 integer) or a list A,B,C") from None
        if not vals.size:
            raise InputError(f"--vary {item!r}: no values")
        if name in out:  # the last one used to win silently
            raise InputError(f"--vary {name}: given twice")
        out[name] = vals
    return out


MAX_SWEEP_POINTS = 1_000_000  # designs in one sweep (one batch); docs/security.md


def grid(vary: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Full factorial: every combination, the first variable varying slowest."""
    names = list(vary)
    total = math.prod(len(vary[n]) for n in names)
    if total > MAX_SWEEP_POINTS:
        raise InputError(f"--vary: a grid of {total} designs; a sweep holds at most {MAX_SWEEP_POINTS}")
    combos = np.array(list(itertools.product(*[vary[n] for n in names])), dtype=float)
    return {n: combos[:, j] for j, n in enumerate(names)}


def read_list(path: str, config) -> dict[str, np.ndarray]:
    """A header of names, each a design variable or parameter of the run (``config``), or a column the run
    computes (an output, ``margin.*``, feasible, ok, error: a sweep.csv or a Pareto front read back; left out, with
    a note), then one row of numbers per design; InputError naming the row and column."""
    from bev_mdo.models.cycles import csv_number, read_csv_rows

    try:  # the reader of every user CSV (size-bounded, UTF-8 with or without BOM, one-line errors)
        rows = [r for r in read_csv_rows(path, "design list") if any(c.strip() for c in r)]
    except ValueError as exc:
        raise InputError(f"--list: {exc}") from None
    if len(rows) < 2:
        raise InputError(f"--list {path}: no designs (a header of names, then one row per design)")
    names = [c.strip() for c in rows[0]]
    twice = sorted({n for n in names if names.count(n) > 1})
    if "" in names or twice:  # the last column of a name used to win silently
        raise InputError(f"--list {path}: the header " + (f"names {twice[0]!r} twice" if twice else "has an empty name"))
    params = sorted({p for d in config.disciplines for p in getattr(d, "parameters", None) or ()})
    # what a run writes beside its designs (sweep.csv, pareto front.csv): recomputed, not read
    outputs = {o for d in config.disciplines for o in d.outputs} | {"feasible", "ok", "error"}
    computed = [n for n in names if n in outputs or n.startswith("margin.")]
    unknown = [n for n in names if n not in config.problem.names and n not in params and n not in computed]
    if unknown:  # said before its cells: a column of labels was 'not a number'
        from bev_mdo.mdo.vectors import did_you_mean

        raise InputError(f"--list {path}: column {unknown[0]!r} is not a design variable or parameter; "
                         f"{did_you_mean(unknown[0], [*config.problem.names, *params])}design "
                         f"variables: {config.problem.names}, parameters: {params}")
    if computed:
        print(f"bev-mdo sweep: note: --list {path}: columns {', '.join(computed)} are what a run computes: "
              "computed again, not read", file=sys.stderr)
    values = np.empty((len(rows) - 1, len(names)))
    for i, row in enumerate(rows[1:]):
        if len(row) != len(names):
            raise InputError(f"--list {path}: design {i + 1} has {len(row)} values for {len(names)} names")
        for j, cell in enumerate(row):
            if names[j] in computed:
                continue
            try:
                values[i, j] = csv_number(cell)
            except ValueError as exc:  # not a number (1_0 was 10), or not finite
                raise InputError(f"--list {path}: design {i + 1}, column {names[j]!r}: {exc}") from None
    return {n: values[:, j] for j, n in enumerate(names) if n not in computed}


def write_csv(path: Path, result: dict) -> None:
    """``sweep.csv``, whole or not at all: written beside and renamed (a signal while it was written left
    part of the rows under the final name, with nothing to say so)."""
    cols = list(result["design"]) + list(result["outputs"]) + [f"margin.{k}" for k in result["margins"]]
    n = len(result["feasible"])
    part = path.with_name(path.name + ".part")
    with open(part, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(cols + ["feasible", "ok", "error"])
        for i in range(n):
            row = [result["design"][k][i] for k in result["design"]] + [result["outputs"][k][i] for k in result["outputs"]]
            row += [result["margins"][k][i] for k in result["margins"]]
            w.writerow([f"{v:.10g}" for v in row] + [bool(result["feasible"][i]), bool(result["ok"][i]),
                                                     result["errors"][i]])
    os.replace(part, path)


@styled
def plot_output(result: dict, output: str, varied: list[str], path: Path, baseline: dict | None = None):
    """One PNG: ``output`` against the first varied variable, one line per value of the second
    (if any; further varied variables: one panel per value of the third is too much, they are
    overlaid); feasible points filled, infeasible hollow red x; constraint limits dashed. The x-axis spans the
    swept values (the bounds dotted where the sweep reaches them), the legend beside the axes."""
    from bev_mdo.api.evaluate import axis_label

    label = axis_label(result.get("units"))
    problem = result["problem"]
    x = result["design"][varied[0]]
    y = result["outputs"][output]
    feas = result["feasible"]
    groups = [(None, np.ones(len(x), bool))]
    if len(varied) > 1:
        second = result["design"][varied[1]]
        groups = [(v, np.isclose(second, v)) for v in np.unique(second)]
    ncol = 1 + (len(groups) + 5) // 28  # the legend's columns, beside the axes: up to ~28 entries each
    fig, ax = subplots(figsize=(7 + 2.6 * ncol, 4.6), layout="constrained")
    cmap = colormap("viridis")
    for k, (v, sel) in enumerate(groups):
        colour = cmap(k / max(len(groups) - 1, 1)) if v is not None else "C0"
        order = np.argsort(x[sel], kind="stable")
        xs, ys, fs = x[sel][order], y[sel][order], feas[sel][order]
        lab = f"{label(varied[1])} = {v:g}" if v is not None else None
        ax.plot(xs, ys, "-", color=colour, lw=1, alpha=0.7, label=lab)
        ax.plot(xs[fs], ys[fs], "o", color=colour, ms=5)
        ax.plot(xs[~fs], ys[~fs], "x", color="C3", ms=7, mew=1.5)
    lo, hi = float(np.min(x)), float(np.max(x))  # the axis spans the swept values, not the bounds
    pad = 0.04 * (hi - lo) if hi > lo else 0.05 * max(abs(lo), 1.0)
    if baseline and varied[0] in baseline["design"] and output in baseline["outputs"]:
        bx = baseline["design"][varied[0]]
        # with lines per value of a second variable, the star is at the baseline's own value of it: said
        own = "".join(f"\n{k}={baseline['design'][k]:g}" for k in varied[1:] if k in baseline["design"])
        if lo - pad <= bx <= hi + pad:
            ax.plot([bx], [baseline["outputs"][output]], "*", color="k", ms=12,
                    label=f"baseline ({baseline['name']}){own}")
        else:  # drawn, it would stretch the y-axis to a point off the x-axis
            ax.plot([], [], "*", color="k", ms=12,
                    label=f"baseline ({baseline['name']}):\n{varied[0]}={bx:g}, outside the swept range")
    ax.plot([], [], "o", color="0.4", label="feasible")
    ax.plot([], [], "x", color="C3", label="infeasible")
    for c in problem.constraints:
        if c.name == output:
            for kind, b in (("lower", c.lower), ("upper", c.upper)):
                if b is not None:
                    ax.axhline(b, color="C3", ls="--", lw=1.2, label=f"constraint {'≥' if kind == 'lower' else '≤'} {b:g}")
    for d in problem.design_variables:
        if d.name == varied[0]:
            for b in (d.lower, d.upper):
                if lo - pad <= b <= hi + pad:  # a bound the sweep reaches
                    ax.axvline(b, color="0.3", ls=":", lw=1)
    ax.set_xlim(lo - pad, hi + pad)
    ax.set_xlabel(label(varied[0]))
    ax.set_ylabel(label(output))
    fixed = ", ".join(f"{k}={result['design'][k][0]:g}" for k in result["design"] if k not in varied)
    ax.set_title(f"{label(output)} vs {label(varied[0])}" + (f"\n(fixed: {fixed})" if fixed else ""), fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=ncol, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)  # hides no data
    fig.savefig(path, dpi=100)
    return fig, ax


def designs_of(args, config) -> tuple[dict[str, np.ndarray], list[str]]:
    """(the designs the command line asks for, the names varied): a DOE over the bounds of the design
    variables not fixed with --set, a grid (--vary) or a list (--list), with the --set values as columns."""
    from bev_mdo.api.doe import batch
    from bev_mdo.cli.flags import parse_assignments

    if sum(map(bool, (args.doe, args.vary, args.list_csv))) != 1:
        raise InputError("give one of --doe METHOD --samples N, --vary NAME=LO:HI:N ... or --list FILE.csv")
    if not args.doe and (args.samples, args.seed) != (None, None):  # they were ignored without a word
        raise InputError("--samples and --seed go with --doe (--vary and --list evaluate the designs they give)")
    args.samples, args.seed = 64 if args.samples is None else args.samples, 1 if args.seed is None else args.seed
    given = None if args.doe else grid(parse_vary(args.vary)) if args.vary else read_list(args.list_csv, config)
    fixed = parse_assignments(args.fixed)
    designs = batch(config.problem, args.doe, args.samples, args.seed, given, fixed, "--set")
    return designs, [k for k in designs if k not in fixed]


def run(args) -> int:
    from bev_mdo.api.doe import plot_scatter, record
    from bev_mdo.api.transport import Transport
    from bev_mdo.cli import flags

    config = flags.load_config(args)
    out = Path(args.out)
    bag = out / "bag"
    claim = contextlib.nullcontext()
    if not args.no_record:  # held until the bag is written: of two sweeps given the same --out at once one is refused
        from bev_mdo.api.runbag import claim_new_bag

        claim = claim_new_bag(bag, "--out", out)
    with claim:
        designs, varied = designs_of(args, config)
        n = len(next(iter(designs.values())))
        transport = "ros" if Transport.of(args).uses_ros else "inprocess"
        result = evaluate_batch(config, designs, args)
        out.mkdir(parents=True, exist_ok=True)
        written = [out / "sweep.csv"]
        if not args.no_record:  # the bag first: whatever stops the command after the batch, the batch is recorded
            written.append(record(bag, config, result, args.doe or ("grid" if args.vary else "list"), transport,
                                  flags.parse_assignments(args.fixed)))
    write_csv(out / "sweep.csv", result)
    if not args.no_plots:
        from bev_mdo.sessions import analyse_baseline

        # the config's baseline, analysed in process (a failed one has no outputs and is not drawn)
        baseline = analyse_baseline(config) if not args.doe or args.doe == "full" else None
        for o in result["outputs"]:
            if o in varied:
                continue
            p = out / f"{o}.png"
            if args.doe and args.doe != "full":
                plot_scatter(result, o, varied, p, f"{args.doe}, seed {args.seed}")
            else:
                plot_output(result, o, varied, p, baseline)
            written.append(p)
    feas = result["feasible"]
    print(f"{n} design{'s' if n != 1 else ''} in one batch ({transport}): {int(feas.sum())} feasible, {int((~feas).sum())} infeasible, "
          f"{int((~result['ok']).sum())} failed")
    if feas.any():
        obj = result["outputs"][result["objective"]]
        maximize = bool(getattr(result["problem"], "maximize", False))
        i = int(np.argmax(np.where(feas, obj, -np.inf)) if maximize else np.argmin(np.where(feas, obj, np.inf)))
        best = ", ".join(f"{k}={result['design'][k][i]:.6g}" for k in result["design"])
        print(f"best feasible {result['objective']} = {obj[i]:.6g} at {best}")
    for note in result["notes"]:
        print(f"note: {note}")
    for p in written:
        print(p)
    return failures_said(result, "sweep", " (sweep.csv: error)")


def failures_said(result: dict, command: str, where: str = "") -> int:
    """stderr counts the batch's failed designs with the first one's reason (sweep's was in sweep.csv alone); the
    status: 1 when every design failed, as evaluate's failure, else 0."""
    ok = np.asarray(result["ok"], dtype=bool)
    if not ok.all():
        i = int(np.flatnonzero(~ok)[0])
        first = str(result["errors"][i]).splitlines()[0]
        print(f"bev-mdo {command}: {'every design' if not ok.any() else f'{int((~ok).sum())} of {ok.size} designs'} "
              f"failed; the first (design {i + 1}): {first}{where}", file=sys.stderr)
    return 0 if ok.any() else 1


def run_compare(args) -> int:
    from bev_mdo.api.evaluate import check_names, notes_of
    from bev_mdo.cli.flags import parse_assignments
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo import units as un

    if len(args.design) < 2:
        raise InputError("give two or more --design k=v,... to compare")
    config = RunConfig.load(args.config)
    given = [parse_assignments(d, "--design") for d in args.design]
    keys = list(dict.fromkeys(k for g in given for k in g))
    problem = config.problem
    init = {d.name: d.initial for d in problem.design_variables}
    designs = {k: np.array([g.get(k, init.get(k, np.nan)) for g in given]) for k in keys}
    check_names(keys, problem, {p for d in config.disciplines for p in (getattr(d, "parameters", None) or {})})
    missing = [k for k, v in designs.items() if np.isnan(v).any()]
    if missing:
        raise InputError(f"{missing} must be given in every --design (they are parameters, with no initial value)")
    result = evaluate_batch(config, designs, args)

    def unit_of(name):
        return un.unit_of(name, result["units"])

    named = {**result["design"], **{k: v for k, v in result["outputs"].items() if k not in result["design"]}}
    rows = [(k, unit_of(k), v) for k, v in named.items()]
    rows += [(f"margin {k}", unit_of(k), v) for k, v in result["margins"].items()]
    notes = [result["outside"][i] + notes_of(config, {**problem.parameters, **{k: v[i] for k, v in result["design"].items()}},
                                             {k: v[i] for k, v in result["outputs"].items()})[1]  # why 'NO'
             for i in range(len(given))]
    if args.json:
        print(jsontext.dumps({"designs": [{name: float(v[i]) for name, _, v in rows} | {
            "feasible": bool(result["feasible"][i]), "ok": bool(result["ok"][i])} | (
            {"notes": notes[i]} if notes[i] else {}) for i in range(len(given))]}))
        return failures_said(result, "compare")
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"{len(given)} designs; differences from design 1")
    t.add_column("quantity")
    t.add_column("unit")
    t.add_column("design 1", justify="right")
    for i in range(1, len(given)):
        t.add_column(f"design {i + 1}", justify="right")
        t.add_column(f"Δ {i + 1}−1", justify="right")
    for name, unit, v in rows:
        big = float(np.max(np.abs(v[np.isfinite(v)]), initial=1.0))  # (nanmax warned of a row failed in every design)

        def num(x, sign=""):  # round-off (below 1e-9 of the row's largest value) shows as 0
            return "0" if abs(x) < 1e-9 * big else f"{x:{sign}.6g}"

        cells = [num(v[0])]
        for i in range(1, len(given)):
            d = v[i] - v[0]
            # of |design 1|: a negative quantity that rises must not read as a fall ('+8 (-1.1 %)'); none of a margin
            # (a constraint's, or an output such as drive_torque_margin_nm), whose zero is no reference: +13327 %
            pct = f" ({100 * d / abs(v[0]):+.1f} %)" if v[0] != 0.0 and np.isfinite(v[0]) and "margin" not in name else ""
            cells += [num(v[i]), f"{num(d, '+')}{pct}" if num(d) != "0" else "0"]
        t.add_row(name, unit, *cells)
    feas = ["yes" if f else "[bold red]NO[/]" for f in result["feasible"]]
    t.add_row("feasible", "", feas[0], *[c for f in feas[1:] for c in (f, "")])
    Console(file=sys.stdout, width=max(100, 40 + 28 * len(given))).print(t)
    for i, lines in enumerate(notes):
        for note in lines:
            print(f"note: design {i + 1}: {note}")
    return failures_said(result, "compare")
