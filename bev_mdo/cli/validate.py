"""``bev-mdo validate [--data CSV] [--energy-model M] [--parameter-set NAME] [--pairs] [--png FILE] [--json]``.

Runs every vehicle of a fleet file (EPA Test Car List columns, default: the shipped EPA 2022
BEV training fleet) on UDDS and HWFET in one batch per cycle and prints predicted against
measured wall energy per vehicle, then the mean, median, 90th-percentile and maximum absolute
percentage error. Vehicles whose rated power cannot follow a cycle are listed as such and
left out of the statistics; so are rows flagged as outliers in the file. ``--png`` draws a
parity plot with the +-5 % band and the residuals against test mass and rated power.
``--pairs`` adds the within-family pairs (bev_mdo/models/pairs.py): each pair's measured and
predicted percentage difference per cycle, the slope of predicted on measured and the mean
absolute difference against their targets; with ``--png`` it draws those instead of the parity plot.
Models: chain (default; wall to wheel with the calibrated parameter set), flat, breakdown (the
thesis models, which stop at the battery terminals), quasi_static, topology_sm_sa (the thesis'
model with its motor written as losses and calibrated to the fleet, from the wall; with
``--parameter-set thesis`` as published, at the battery terminals).
"""
from __future__ import annotations

import json
import math
import sys

import numpy as np

from bev_mdo.cli import UsageError, figure_format

DEFAULT_SET = "epa2022_chain"
# the calibrated set each model is validated with unless --parameter-set names another ('none': defaults)
DEFAULT_SETS = {"chain": DEFAULT_SET, "quasi_static": "epa2022_quasi_static", "topology_sm_sa": "epa2022_quasi_static"}


def compared(energy_model: str, base: dict | None = None) -> str:
    """What validate compares: the measured figure is EPA's energy from the wall; the chain predicts the
    same quantity (a run's energy_wall_wh_per_km), the thesis models the energy from the battery
    (energy_wh_per_km), which leaves out the charger's loss."""
    if energy_model == "chain":
        return "measured wall energy (EPA, AC recharge) vs predicted wall energy (energy_wall_wh_per_km)"
    if base and "charger_efficiency" in base:
        return ("measured wall energy (EPA, AC recharge) vs predicted wall energy (energy_wh_per_km / the "
                "parameter set's charger_efficiency)")
    return ("measured wall energy (EPA, AC recharge) vs predicted battery energy (energy_wh_per_km: "
            f"{energy_model} stops at the battery terminals, no charger loss)")


def register(subparsers) -> None:
    from bev_mdo.models.fleet import ENERGY_MODELS

    p = subparsers.add_parser("validate", help="predicted vs measured energy over a fleet of tested vehicles",
                              description=__doc__.splitlines()[0])
    p.add_argument("--data", metavar="CSV", default=None,
                   help="fleet file (default: bev_mdo/data/epa_2022_bev/train.csv)")
    p.add_argument("--energy-model", default="chain", choices=ENERGY_MODELS, help="energy model (default chain)")
    p.add_argument("--parameter-set", default=None, metavar="NAME",
                   help="parameter set of the chain, quasi_static and topology_sm_sa models: a shipped name or a .yaml "
                        f"path (default {DEFAULT_SET} for chain, {DEFAULT_SETS['quasi_static']} for the other two; "
                        "'thesis' = the thesis' constants, 'none' = model defaults)")
    p.add_argument("--pairs", action="store_true",
                   help="also report within-family pairs: measured vs predicted percentage differences")
    p.add_argument("--png", metavar="FILE", help="write the parity and residual plots (with --pairs: the pairs plot)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def evaluate(data=None, energy_model: str = "chain", parameter_set: str | None = None,
             pairs: bool = False) -> dict:
    """The whole validation as a dict (what --json prints)."""
    from bev_mdo.models import fleet as fl
    from bev_mdo.models.params import load_parameter_set

    fleet = fl.read_fleet(data)
    base = {}
    parameter_set = DEFAULT_SETS.get(energy_model) if parameter_set is None else parameter_set
    if energy_model in DEFAULT_SETS and parameter_set and parameter_set != "none":
        base = load_parameter_set(parameter_set)
    pred = fl.predict(fleet, energy_model, base)
    err = fl.abs_pct_errors(fleet, pred)
    out_rows = []
    scored = {}
    for c in fl.CYCLES:
        scored[c] = pred[c]["follows"] & ~fleet.outlier
    for i in range(len(fleet)):
        row = {"row": int(fleet.rows[i]), "make": fleet.make[i], "model": fleet.model[i],
               "test_mass_kg": float(fleet.test_mass_kg[i]), "rated_power_kw": float(fleet.rated_power_kw[i]),
               "outlier": bool(fleet.outlier[i])}
        for c in fl.CYCLES:
            short = c.replace("epa_", "")
            row[f"{short}_measured_wh_per_km"] = float(fleet.measured[c][i])
            row[f"{short}_predicted_wh_per_km"] = float(pred[c]["energy_wh_per_km"][i])
            row[f"{short}_error_pct"] = float(err[c][i])
            row[f"{short}_follows"] = bool(pred[c]["follows"][i])
        out_rows.append(row)
    both = np.concatenate([err[c][scored[c]] for c in fl.CYCLES])
    report = {"data": fleet.path, "energy_model": energy_model, "compared": compared(energy_model, base),
              "parameter_set": parameter_set if energy_model in DEFAULT_SETS else None,
              "vehicles": len(fleet), "rows": out_rows,
            "not_following": [{"row": int(fleet.rows[i]), "cycle": c} for c in fl.CYCLES
                              for i in np.flatnonzero(~pred[c]["follows"])],
            "stats": {"udds_hwfet": fl.error_stats(both),
                      **{c.replace("epa_", ""): fl.error_stats(err[c][scored[c]]) for c in fl.CYCLES}},
              "by_make": _by_make(fleet, err, scored)}
    if pairs:
        report["pairs"] = _pairs(fleet, pred, scored)
    return report


def _pairs(fleet, pred: dict, scored: dict) -> dict:
    """Within-family pairs per cycle: a pair counts on a cycle when both vehicles are scored there."""
    from bev_mdo.models import fleet as fl
    from bev_mdo.models import pairs as pr

    family = fleet.model_line()
    all_pairs = pr.find_pairs(family, fleet.drive, fleet.rated_power_kw, fleet.test_mass_kg, ~fleet.outlier)
    out = {"rule": "same make and model line (Fleet.model_line), different drive class, rated power or test mass; "
                   "A = earlier row, diff = 100 (E_B / E_A - 1)",
           "slope": "least squares through the origin, predicted on measured", "families": len(set(family)),
           "pairs": len(all_pairs)}
    for c in fl.CYCLES:
        ok = [(a, b) for a, b in all_pairs if scored[c][a] and scored[c][b]]
        meas, predicted = pr.pct_diff(fleet.measured[c], ok), pr.pct_diff(pred[c]["energy_wh_per_km"], ok)
        out[c.replace("epa_", "")] = {
            **pr.pair_stats(meas, predicted),
            "rows": [{"family": family[a], "a_row": int(fleet.rows[a]), "b_row": int(fleet.rows[b]),
                      "a_model": fleet.model[a], "b_model": fleet.model[b],
                      "a_drive": pr.drive_class(fleet.drive[a]), "b_drive": pr.drive_class(fleet.drive[b]),
                      "measured_pct": float(m), "predicted_pct": float(p)}
                     for (a, b), m, p in zip(ok, meas, predicted)]}
    return out


def _by_make(fleet, err: dict, scored: dict) -> list[dict]:
    """Error statistics of each make over its scored vehicle-cycles, most over-predicted first: the
    chain's errors go by make (docs/validation.md), which the fleet-wide figures hide."""
    from bev_mdo.models import fleet as fl

    makes = np.array([m.strip().lower() for m in fleet.make])
    out = []
    for key in dict.fromkeys(makes):
        e = np.concatenate([err[c][scored[c] & (makes == key)] for c in err])
        if e.size:
            name = next(m.strip() for m in fleet.make if m.strip().lower() == key)
            out.append({"make": name, "vehicles": int((makes == key).sum()), **fl.error_stats(e)})
    return sorted(out, key=lambda r: -r["mean_signed_pct"])


def run(args) -> int:
    from bev_mdo.models.fleet import ENERGY_MODELS

    if args.energy_model not in ENERGY_MODELS:
        raise UsageError(f"--energy-model must be one of {list(ENERGY_MODELS)}")
    report = evaluate(args.data, args.energy_model, args.parameter_set, pairs=args.pairs)
    if args.png:
        plot_pairs(report, args.png) if args.pairs else plot(report, args.png)
    if args.json:
        print(json.dumps(report, indent=2, allow_nan=True))
    else:
        print_table(report)
        if args.pairs:
            print_pairs(report)
    return 0


def _f(x, nd=1):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def print_table(report: dict, file=None) -> None:
    out = file or sys.stdout
    ps = f", parameter set {report['parameter_set']}" if report.get("parameter_set") else ""
    print(f"{report['data']}: {report['vehicles']} vehicles, energy model {report['energy_model']}{ps}; "
          f"Wh/km, {report['compared']}", file=out)
    print(f"{'row':>4} {'make':10} {'model':34} {'kg':>6} {'kW':>5} | {'UDDS meas':>9} {'pred':>7} {'err%':>6} | "
          f"{'HWFET meas':>10} {'pred':>7} {'err%':>6}", file=out)
    for r in report["rows"]:
        cells = []
        for c, w in (("udds", 9), ("hwfet", 10)):
            note = "" if r[f"{c}_follows"] else " CANNOT FOLLOW"
            cells.append(f"{r[f'{c}_measured_wh_per_km']:>{w}.1f} {r[f'{c}_predicted_wh_per_km']:>7.1f} "
                         f"{r[f'{c}_error_pct']:>+6.1f}{note}")
        flag = " (outlier, not scored)" if r["outlier"] else ""
        print(f"{r['row']:>4} {r['make'][:10]:10} {r['model'][:34]:34} {r['test_mass_kg']:>6.0f} "
              f"{r['rated_power_kw']:>5.0f} | {cells[0]} | {cells[1]}{flag}", file=out)
    for name, s in report["stats"].items():
        print(f"{name:>11}: n={s['n']:3d}  mean |err| {_f(s['mean_abs_pct'], 2)} %  median {_f(s['median_abs_pct'], 2)} %"
              f"  P90 {_f(s['p90_abs_pct'], 2)} %  max {_f(s['max_abs_pct'], 2)} %  mean signed {_f(s['mean_signed_pct'], 2)} %",
              file=out)
    if report.get("by_make") and len(report["by_make"]) > 1:
        print("by make, both cycles (mean signed % / mean |err| %): " + ", ".join(
            f"{r['make']} {r['mean_signed_pct']:+.1f} / {r['mean_abs_pct']:.1f}" for r in report["by_make"]), file=out)
    if report["not_following"]:
        print(f"{len(report['not_following'])} vehicle-cycle(s) whose rated power cannot follow the cycle "
              f"(not scored): " + ", ".join(f"row {x['row']} {x['cycle']}" for x in report["not_following"]), file=out)


def plot(report: dict, path: str) -> None:
    """Parity plot with the +-5 % band, residuals against test mass and rated power."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = report["rows"]
    fig, ax = plt.subplots(1, 3, figsize=(15, 4.8))
    marks = {"udds": ("o", "UDDS"), "hwfet": ("s", "HWFET")}
    lo, hi = math.inf, 0.0
    for c, (mk, label) in marks.items():
        ok = [r for r in rows if r[f"{c}_follows"] and not r["outlier"]]
        bad = [r for r in rows if not (r[f"{c}_follows"] and not r["outlier"])]
        meas = np.array([r[f"{c}_measured_wh_per_km"] for r in ok])
        pred = np.array([r[f"{c}_predicted_wh_per_km"] for r in ok])
        e = np.array([r[f"{c}_error_pct"] for r in ok])
        ax[0].scatter(meas, pred, marker=mk, label=label, alpha=0.75)
        if bad:
            ax[0].scatter([r[f"{c}_measured_wh_per_km"] for r in bad], [r[f"{c}_predicted_wh_per_km"] for r in bad],
                          marker="x", color="k", label=f"{label}: not scored")
        ax[1].scatter([r["test_mass_kg"] for r in ok], e, marker=mk, label=label, alpha=0.75)
        ax[2].scatter([r["rated_power_kw"] for r in ok], e, marker=mk, label=label, alpha=0.75)
        if meas.size:
            lo, hi = min(lo, meas.min(), pred.min()), max(hi, meas.max(), pred.max())
    if not math.isfinite(lo):
        lo, hi = 50.0, 300.0
    x = np.array([lo * 0.95, hi * 1.05])
    ax[0].plot(x, x, "k-", lw=1)
    ax[0].fill_between(x, 0.95 * x, 1.05 * x, color="grey", alpha=0.2, label="+-5 %")
    ax[0].set(xlabel="measured wall energy (Wh/km)", title="parity",
              ylabel=f"predicted {'wall' if report['energy_model'] == 'chain' else 'battery'} energy (Wh/km)")
    s = report["stats"]["udds_hwfet"]
    ax[0].text(0.02, 0.98, f"mean |err| {_f(s['mean_abs_pct'], 2)} %\nP90 {_f(s['p90_abs_pct'], 2)} %",
               transform=ax[0].transAxes, va="top")
    for a, xl in ((ax[1], "test mass (kg)"), (ax[2], "rated power (kW)")):
        a.axhspan(-5, 5, color="grey", alpha=0.2)
        a.axhline(0, color="k", lw=1)
        a.set(xlabel=xl, ylabel="error %", title=f"residual vs {xl.split(' (')[0]}")
    for a in ax:
        a.legend(loc="lower right", fontsize=8)
        a.grid(alpha=0.3)
    fig.suptitle(f"{report['energy_model']} on {report['data'].rsplit('/', 1)[-1]}")
    _save(fig, path)


def _met(flag) -> str:
    return "-" if flag is None else ("met" if flag else "NOT met")


def print_pairs(report: dict, file=None) -> None:
    out = file or sys.stdout
    pairs = report["pairs"]
    if not pairs["pairs"]:
        print(f"pairs: none in {report['data']} (no two rows of one model family differ in drive, "
              f"rated power or test mass)", file=out)
        return
    print(f"within-family pairs ({pairs['pairs']} pairs in {pairs['families']} families; B over A, %; "
          f"slope by least squares through the origin):", file=out)
    print(f"{'cycle':6} {'A row':>5} {'B row':>5} {'A model':30} {'B model':30} {'meas%':>7} {'pred%':>7} "
          f"{'diff':>6}", file=out)
    for c in ("udds", "hwfet"):
        for r in pairs[c]["rows"]:
            print(f"{c:6} {r['a_row']:>5} {r['b_row']:>5} {r['a_model'][:30]:30} {r['b_model'][:30]:30} "
                  f"{r['measured_pct']:>+7.1f} {r['predicted_pct']:>+7.1f} "
                  f"{r['predicted_pct'] - r['measured_pct']:>+6.1f}", file=out)
    for c in ("udds", "hwfet"):
        s = pairs[c]
        lo, hi = s["slope_target"]
        print(f"pairs {c:>5}: n={s['n']:3d}  slope {_f(s['slope_through_origin'], 2)} (target {lo}-{hi}: "
              f"{_met(s['slope_met'])})  mean |diff| {_f(s['mean_abs_diff_points'], 2)} points "
              f"(target <= {s['mean_abs_diff_target_points']}: {_met(s['mean_abs_diff_met'])})", file=out)


def plot_pairs(report: dict, path: str) -> None:
    """Predicted against measured percentage difference (B over A) of each pair, one panel per
    cycle, with y = x, the +-2.5-point band and the fitted slope through the origin."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pairs = report["pairs"]
    fig, ax = plt.subplots(1, 2, figsize=(11, 5))
    for a, (c, label) in zip(ax, (("udds", "UDDS"), ("hwfet", "HWFET"))):
        s = pairs[c]
        x = np.array([r["measured_pct"] for r in s["rows"]])
        y = np.array([r["predicted_pct"] for r in s["rows"]])
        span = max(5.0, float(np.abs(np.concatenate([x, y])).max()) * 1.1) if x.size else 10.0
        line = np.array([-span, span])
        band = s["mean_abs_diff_target_points"]
        a.fill_between(line, line - band, line + band, color="grey", alpha=0.2, label=f"y = x +- {band} points")
        a.plot(line, line, "k-", lw=1, label="y = x")
        if s["slope_through_origin"] is not None:
            a.plot(line, s["slope_through_origin"] * line, "r--", lw=1,
                   label=f"fit through origin, slope {s['slope_through_origin']:.2f}")
        a.scatter(x, y, alpha=0.75, label=f"{s['n']} pairs")
        a.set(xlim=(-span, span), ylim=(-span, span), xlabel="measured difference B over A (%)",
              ylabel="predicted difference B over A (%)",
              title=f"{label}: mean |diff| {_f(s['mean_abs_diff_points'], 2)} points")
        a.legend(loc="upper left", fontsize=8)
        a.grid(alpha=0.3)
    fig.suptitle(f"within-family pairs, {report['energy_model']} on {report['data'].rsplit('/', 1)[-1]}")
    _save(fig, path)


def _save(fig, path) -> None:
    """Write a figure (format from the name) and close it; an unwritable path is one ValueError."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    try:
        fig.savefig(path, dpi=110, format=figure_format(path))
    except OSError as exc:
        raise ValueError(f"cannot write {path}: {exc.strerror}") from None
    finally:
        plt.close(fig)
