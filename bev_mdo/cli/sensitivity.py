"""``bev-mdo sensitivity CONFIG --at k=v,... [--order 1|2] [--wrt a,b] [--json] [--png FILE]``;
``--global sobol|morris --samples N --seed S``: global indices over the bounds (bev_mdo.api.sensitivity).

Normalised first-order (eq 5-4, like Table 7-2) and second-order (eq 5-5, like Table
7-3 / Fig 5-3, with NC/MC/SC/VSC labels) sensitivities of the objective and of every
constrained output, by batched FD through the in-process MDA: one MDA batch per stencil.
``--wrt`` may name design variables and model parameters (sent as override columns).
Coupling thresholds: |S'| < 0.05 NC, < 0.5 MC, < 0.8 SC, else VSC.
"""
from __future__ import annotations

import sys

import numpy as np

from bev_mdo import jsontext
from bev_mdo.figures import colormap, figure, styled

ROUGH = 0.01  # a value is marked "~" when its error estimate (Richardson's, or half a kink's jump) is over 1 % of it
_ROUGH_LINE = (f"~ uncertain by over {ROUGH:.0%} of the value: the estimates with steps h and 2h, or the slopes either "
               "side of the point, differ (a kink or noise near the point{}try another --rel-step; check-totals)")


def register(subparsers) -> None:
    from bev_mdo.api.sensitivity import METHODS
    from bev_mdo.cli.flags import add_override_arguments, add_transport_arguments, seed

    p = subparsers.add_parser("sensitivity")
    p.add_argument("config", help="run config YAML")
    p.add_argument("--at", default="", metavar="K=V,...",
                   help="design point (design variables default to their initial values); with --global, the "
                        "values of the variables not analysed")
    p.add_argument("--order", type=int, choices=(1, 2), default=None, help="local: 1 or 2 (default 2)")
    p.add_argument("--wrt", default="", metavar="NAMES",
                   help="comma-separated design variables and/or model parameters (default: design variables; "
                        "--global: design variables only)")
    p.add_argument("--method", choices=("central", "complex", "auto"), default="central",
                   help="first-order derivative method; the MDA passes float64 values between disciplines, "
                        "so complex step is not available here (auto is central)")
    p.add_argument("--rel-step", type=float, default=None, help="relative FD step (default 1e-4 / 1e-3)")
    g = p.add_argument_group("global sensitivity (SALib) over the design variables' bounds")
    g.add_argument("--global", dest="global_method", choices=METHODS, default=None,
                   help="sobol: first-order and total Sobol' indices; morris: elementary-effects screening")
    g.add_argument("--samples", type=int, default=None,
                   help="sobol: base sample N, a power of 2, N (D + 2) designs (default 1024); "
                        "morris: trajectories, N (D + 1) designs (default 64)")
    g.add_argument("--seed", type=seed, default=None, help="random seed of the sampling and the bootstrap (default 1)")
    g.add_argument("--conf-level", type=float, default=None, help="confidence level of the intervals (default 0.95)")
    p.add_argument("--json", action="store_true", help="print JSON instead of tables")
    p.add_argument("--png", metavar="FILE", help="write a PNG: first-order bars and (order 2) the second-order "
                                                 "matrices; --global: the indices with their intervals")
    add_transport_arguments(p)
    add_override_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.api import sensitivity
    from bev_mdo.api.transport import Transport
    from bev_mdo.api.errors import InputError
    from bev_mdo.cli import figure_format, flags

    if args.png:
        figure_format(args.png)  # a folder or standard output: refused before any evaluation
    glob = ("samples", "seed", "conf_level")  # a flag of the other kind was ignored without a word
    wrong = [f"--{k.replace('_', '-')}" for k in (("order", "rel_step") if args.global_method else glob)
             if getattr(args, k) is not None]
    if wrong:
        raise InputError(f"{', '.join(wrong)}: " + ("local sensitivities only (without --global)"
                                                    if args.global_method else "needs --global sobol|morris"))
    from bev_mdo.mdo.sensitivity import REL_STEP_MAX

    if args.rel_step is not None and not 0 < args.rel_step < REL_STEP_MAX:  # the core names it rel_step (the API's)
        raise InputError(f"--rel-step {args.rel_step:g}: must be in (0, {REL_STEP_MAX:g})")
    cfg = flags.load_config(args)
    wrt = [s.strip() for s in args.wrt.split(",") if s.strip()]
    got = sensitivity.run(cfg, flags.parse_assignments(args.at, "--at"), wrt, Transport.of(args), global_method=args.global_method,
                          order=args.order or 2, rel_step=args.rel_step, method=args.method, samples=args.samples,
                          seed=1 if args.seed is None else args.seed,
                          conf_level=0.95 if args.conf_level is None else args.conf_level)
    if args.global_method:
        from bev_mdo.cli import global_sensitivity as gs

        if args.png:
            gs.write_plot(args.png, got)
        if args.json:
            print(jsontext.dumps(got))
        else:
            gs.print_tables(got)
            if args.png:
                print(f"wrote {args.png}")
        return 0
    s, outputs, point, problem = got
    if args.png:
        from bev_mdo.api.evaluate import declared_units

        write_heatmap(args.png, s, outputs, cfg, {k: point[k] for k in problem.names}, declared_units(cfg))
    from bev_mdo.api.evaluate import design_notes

    notes = design_notes(cfg, {**s.point, **s.values})  # e.g. the 0-100 km/h time of a point that cannot reach 100 km/h
    units = sensitivity.units_of(cfg, [*s.names, *outputs])
    if args.json:
        print(jsontext.dumps(sensitivity.to_dict(s, outputs, units) | ({"notes": notes} if notes else {})))
    else:
        print_tables(s, outputs, shown=problem.names, units=units)
        for note in notes:
            print(f"note: {note}")
        if args.png:
            print(f"wrote {args.png}")
    return 0


def print_tables(s, outputs, out=None, shown=(), units=None) -> None:
    """The tables of a local sensitivity ``s``; its point line names the ``shown`` variables (the design) and
    every ``wrt`` one (a parameter's line left out the design it was taken at); ``units`` ({name: unit}): each
    step's."""
    from bev_mdo.mdo.units import unit_of

    out = out or sys.stdout  # the stream of the call (a default of sys.stdout kept the one at import)
    w = max(12, *(len(n) for n in s.names)) + 2
    ow = max(len(k) for k in outputs) + 2
    print(f"point: {', '.join(f'{k}={s.point[k]:g}' for k in dict.fromkeys([*shown, *s.names]))}   "
          f"({s.n_evaluations} evaluations in {s.n_batches} batch(es), method {s.method})", file=out)
    if s.one_sided:  # the header's method is the others'
        print(f"one-sided differences for {', '.join(s.one_sided)}: on or within two steps of a bound (or a "
              "parameter's model limit), so that every step stays inside it", file=out)
    print("\nFirst-order normalised sensitivity S_i = (x_i/f) df/dx_i  (eq 5-4)", file=out)
    print("output".ljust(ow) + "".join(n.rjust(w) for n in s.names), file=out)
    zero = s.undefined  # f = 0, or 0 but for rounding: S undefined, the plain derivatives are shown
    why = {k: "f = 0" if s.values[k] == 0 else f"f = {s.values[k]:.3g}, 0 but for rounding" for k in zero}
    rough = False
    for k in outputs:
        # a leading space keeps a cell wider than the column (|S| >= 1e8 near a zero of f) apart from the last
        cells = s.gradient[k] if k in zero else s.first[k]
        # "~": steps h and 2h disagree by over ROUGH of the value (JSON "error"): a kink or noise at the point
        err = np.nan_to_num(np.asarray((s.gradient_error or {}).get(k, np.zeros(len(cells))) if k in zero
                                       else s.first_error[k], float))
        marks = ["~" if e > ROUGH * abs(v) and e > 1e-12 else "" for v, e in zip(cells, err)]
        rough = rough or any(marks)
        print(k.ljust(ow) + "".join(((f" {v:.4g}" if k in zero else f" {_fixed(v)}") + m).rjust(w)
                                    for v, m in zip(cells, marks))
              + (f"   df/dx_i ({why[k]}: S undefined)" if k in zero else ""), file=out)
    print("step".ljust(ow) + "".join(f" {v:.3g} {unit_of(n, units or {}, inline=True)}".rstrip().rjust(w)
                                     for n, v in zip(s.names, s.step)), file=out)
    if rough and s.second is None:
        print(_ROUGH_LINE.format("; "), file=out)
    if s.second is None:
        return
    print("\nSecond-order normalised sensitivity S'_ij = (x_i x_j/f) d2f/dx_i dx_j  (eq 5-5)", file=out)
    print("labels: NC |S'|<0.05, MC <0.5, SC <0.8, VSC >=0.8 (no/medium/strong/very strong coupling of two "
          "variables; a diagonal entry, one variable's own curvature, has none: null in --json)", file=out)
    for k in outputs:
        m, lab, err = s.second[k], s.labels(k), s.second_error[k]
        if k in zero:  # the raw d2f and its error (a second review: -1.568e15, unmarked, where S' had been -123~)
            m, err = s.hessian[k], (s.hessian_error or {}).get(k, np.zeros_like(s.hessian[k]))
        print(f"\n{k}  " + (f"({why[k]}: S' undefined; d2f/dx_i dx_j shown)" if k in zero
                             else f"(max error estimate {np.nanmax(err):.1e})"), file=out)
        print("".ljust(w) + "".join(n.rjust(w) for n in s.names), file=out)
        # "~" as in the first-order table: an entry of -0.0002 whose error was 1.6e-3 had the wrong sign, unmarked;
        # an error below half the last digit shown (5e-5) is not marked
        rough_2 = np.nan_to_num(np.asarray(err, float)) > np.maximum(ROUGH * np.abs(m), 1e-12 if k in zero else 5e-5)
        rough = rough or bool(np.triu(rough_2).any())
        for i, n in enumerate(s.names):
            # a label is a coupling's (two variables, Fig 5-3); a diagonal entry is one variable's own curvature
            cells = [((f" {m[i, j]:.4g}" if k in zero else f" {_fixed(m[i, j])}" + (f" {lab[i, j]}" if i != j else ""))
                      + ("~" if rough_2[i, j] else "")).rjust(w)
                     if j >= i else "".rjust(w) for j in range(len(s.names))]
            print(n.ljust(w) + "".join(cells), file=out)
    if rough:
        print("\n" + _ROUGH_LINE.format("); an S' entry whose error exceeds it has no sure sign ("), file=out)


def _fixed(v: float) -> str:
    """v to 4 decimals, with no sign on a value that rounds to 0 (-0.0000 read as a sign)."""
    text = f"{v:.4f}"
    return text[1:] if text == "-0.0000" else text


def _context_title(s, cfg, design=None) -> str:
    """'at <every design variable and analysed parameter>; cycle ..., ... model': the cycle (or cycle mix) the
    energy is computed on (cli.energy_cycle_label), not the config's cycle when that only sets the top speed."""
    from bev_mdo.cli import energy_cycle_label

    cyc = energy_cycle_label(cfg)
    model = (cfg or {}).get("energy_model", "")
    shown = {**(design or {}), **{k: s.point[k] for k in s.names}}
    point = ", ".join(f"{k}={v:g}" for k, v in shown.items())
    # the energy model defaults to flat in every config: named only beside a cycle (not for Ishigami)
    return f"at {point}" + (f"; {cyc}" + (f", {model} model" if model else "") if cyc else "")


@styled
def write_heatmap(path: str, s, outputs, cfg=None, design=None, units=None):
    """The sensitivity figure: a first-order bar chart (eq 5-4) and, with second order, one
    matrix per output (eq 5-5) on ONE symmetric colour scale shared by the whole figure. Entries
    whose magnitude is not above their error estimate (Richardson's, at least the rounding of the stencil's
    values) are masked (grey, "≤ err"), every cell by the same rule: they are noise, not signal. Text is
    white on dark cells. The title names the point and the cycle (or cycle mix) the energy is computed on.
    Returns the figure."""
    from matplotlib.colors import Normalize

    from bev_mdo.api.evaluate import axis_label

    label = axis_label(units)
    second = s.second is not None
    n = len(outputs)
    ncols = 2 if second and n > 1 else 1
    nrows = 1 + (-(-n // ncols) if second else 0)
    fig = figure(figsize=(5.2 * ncols + 1.5, 4.2 + 4.0 * (nrows - 1)), layout="constrained")
    gs = fig.add_gridspec(nrows, ncols)
    ax = fig.add_subplot(gs[0, :])
    width = 0.8 / max(n, 1)
    xs = np.arange(len(s.names))
    for k, out in enumerate(outputs):
        vals, err = np.asarray(s.first[out], float), np.asarray(s.first_error[out], float)
        ax.bar(xs + (k - (n - 1) / 2) * width, vals, width, yerr=np.where(np.isfinite(err), err, 0),
               label=label(out) + (" (0 at the point: S undefined)" if out in s.undefined else ""), capsize=2)
    ax.axhline(0, color="k", lw=0.8)
    ax.set_xticks(xs, [label(v) for v in s.names], fontsize=8)
    ax.set_ylabel("S = (x/f) df/dx (–)")
    ax.set_title("first order, normalised (eq 5-4)", fontsize=9)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    if second:
        mats = {k: np.asarray(s.second[k], float) for k in outputs}
        errs = {k: np.asarray(s.second_error[k], float) for k in outputs}
        signal = [np.abs(m)[np.abs(m) > np.nan_to_num(e, nan=np.inf)] for m, e in
                  ((mats[k], errs[k]) for k in outputs)]
        lim = max([float(np.max(v)) for v in signal if v.size] + [1e-3])
        norm = Normalize(vmin=-lim, vmax=lim)
        cmap = colormap("RdBu_r").with_extremes(bad="0.85")
        im, mat_axes = None, []
        ticks = [label(v) for v in s.names]
        for idx, k in enumerate(outputs):
            ax = fig.add_subplot(gs[1 + idx // ncols, idx % ncols])
            mat_axes.append(ax)
            m, e = mats[k], errs[k]
            masked = ~(np.abs(m) > np.nan_to_num(e, nan=np.inf))
            im = ax.imshow(np.ma.masked_array(m, masked), cmap=cmap, norm=norm)
            lab = s.labels(k)
            for i in range(m.shape[0]):
                for j in range(m.shape[1]):
                    if masked[i, j]:
                        ax.text(j, i, "f = 0" if s.values[k] == 0 else "≤ err", ha="center", va="center",
                                fontsize=7, color="0.35")
                        continue
                    dark = abs(norm(m[i, j]) - 0.5) > 0.3
                    ax.text(j, i, f"{m[i, j]:.3g}" + (f"\n{lab[i, j]}" if i != j else ""), ha="center", va="center", fontsize=8,
                            color="white" if dark else "black")
            ax.set_xticks(range(len(s.names)), ticks, rotation=20, ha="right", fontsize=7)
            ax.set_yticks(range(len(s.names)), ticks if idx % ncols == 0 else [], fontsize=7)
            ax.set_title(f"second order (eq 5-5) of {label(k)}", fontsize=9)
        fig.colorbar(im, ax=mat_axes, shrink=0.8, label="S'_ij (–), one scale for all matrices; grey: |S'| ≤ error")
    fig.suptitle(f"Normalised sensitivities {_context_title(s, cfg, design)}", fontsize=10, wrap=True)
    from bev_mdo.cli import save_figure

    save_figure(fig, path)
    return fig
