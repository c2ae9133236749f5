"""``bev-mdo validate [--data CSV] [--energy-model M] [--parameter-set NAME] [--pairs] [--plot DIR] [--json]``.

Runs every vehicle of a fleet file (EPA Test Car List columns, default: the shipped EPA 2022
BEV training fleet) on UDDS and HWFET in one batch per cycle and prints predicted against
measured wall energy per vehicle and the error statistics, beside two references on the same rows
(bev_mdo/models/baselines.py); ``--pairs`` adds the within-family pairs (bev_mdo/models/pairs.py),
``--plot DIR`` the plots (bev_mdo/cli/validate_plots.py). What is printed, scored and refused, and
the models: docs/validation.md, "bev-mdo validate".
"""
from __future__ import annotations

import math

import numpy as np

from bev_mdo import jsontext

DEFAULT_MODEL = "quasi_static"
# the calibrated set each model is validated with unless --parameter-set names another ('none': defaults)
DEFAULT_SETS = {"chain": "epa2022_chain", "quasi_static": "epa2022_quasi_static",
                "topology_sm_sa": "epa2022_quasi_static"}


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

    p = subparsers.add_parser("validate", description=__doc__.splitlines()[0])
    p.add_argument("--data", metavar="CSV", default=None,
                   help="fleet file (default: bev_mdo/data/epa_2022_bev/train.csv)")
    p.add_argument("--energy-model", default=DEFAULT_MODEL, choices=ENERGY_MODELS,
                   help=f"energy model (default {DEFAULT_MODEL})")
    p.add_argument("--parameter-set", default=None, metavar="NAME",
                   help="parameter set of the model: a shipped name or a .yaml path (default "
                        f"{DEFAULT_SETS['chain']} for chain, {DEFAULT_SETS['quasi_static']} for quasi_static and "
                        "topology_sm_sa, none for flat and breakdown; "
                        "'thesis' = the thesis' constants, 'none' = model defaults)")
    p.add_argument("--pairs", action="store_true",
                   help="also report within-family pairs: measured vs predicted percentage differences")
    p.add_argument("--plot", metavar="DIR", help="write parity.png (parity and residuals) into DIR, with --pairs also "
                   "pairs_udds.png and pairs_hwfet.png (each pair an arrow from variant A to B, every model column)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)


def evaluate(data=None, energy_model: str = DEFAULT_MODEL, parameter_set: str | None = None,
             pairs: bool = False) -> dict:
    """The whole validation as a dict (what --json prints)."""
    from bev_mdo.models import fleet as fl
    from bev_mdo.models.params import fitted_for_another_model, fitted_values, load_parameter_set

    fleet = fl.read_fleet(data)
    base = {}
    parameter_set = DEFAULT_SETS.get(energy_model) if parameter_set is None else parameter_set
    if parameter_set and parameter_set != "none":  # any model's (flat, breakdown: only when given)
        base = load_parameter_set(parameter_set)
        fitted = fitted_for_another_model(parameter_set, energy_model)
        if fitted:
            raise ValueError(f"parameter set {parameter_set!r} was fitted for energy model {fitted}, not "
                             f"{energy_model}: give --energy-model {fitted}")
    cycles = fl.resampled_cycles()
    pred = fl.predict(fleet, energy_model, base, cycles, reference=True)  # one batch: numba's load would cost 0.7 s
    err = fl.abs_pct_errors(fleet, pred)
    out_rows = []
    scored = {c: pred[c]["follows"] & ~fleet.outlier for c in fl.CYCLES}
    if not any(scored[c].any() for c in fl.CYCLES):  # as calibrate's 'no vehicle to fit'
        follows_none = ~np.logical_or.reduce([pred[c]["follows"] for c in fl.CYCLES])
        raise ValueError(f"{fleet.path}: no vehicle to score ({int(fleet.outlier.sum())} of {len(fleet)} flagged as "
                         f"outliers, {int((follows_none & ~fleet.outlier).sum())} cannot follow UDDS or HWFET)")
    if base and fitted_values(parameter_set):  # a calibrated set off by 1.609 on every car: a fleet in Wh/mi?
        fl.note_energy_unit(fleet, pred, scored, energy_model)
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
              "parameter_set": parameter_set,
              "parameter_set_fitted_on": fitted_on_these_rows(parameter_set, fleet.path),
              "vehicles": len(fleet), "rows": out_rows,
            "not_following": [{"row": int(fleet.rows[i]), "cycle": c} for c in fl.CYCLES
                              for i in np.flatnonzero(~pred[c]["follows"])],
            "stats": {"udds_hwfet": fl.error_stats(both),
                      **{c.replace("epa_", ""): fl.error_stats(err[c][scored[c]]) for c in fl.CYCLES}},
              "by_make": _by_make(fleet, err, scored)}
    if pairs:
        report["pairs"] = _pairs(fleet, pred, scored)
    report["reference"] = _reference(fleet, energy_model, pred, scored, out_rows, report.get("pairs"), cycles,
                                     report["compared"])
    return report


def fitted_on_these_rows(parameter_set: str | None, data) -> str:
    """Whether the model's figures are in-sample, as far as the set's provenance (its ``fitted_on``: the
    fleet file, its absolute path and SHA-256) tells: no set; fitted on this file; fitted on another file
    that holds none, some or all of these cars (:func:`training_cars`, where that file is at hand and its
    SHA-256 matches); or unknown."""
    import hashlib
    from pathlib import Path

    from bev_mdo.models.cycles import read_csv_rows
    from bev_mdo.models.params import PARAMETER_SET_DIR, is_parameter_set_file, parameter_set_source

    if not parameter_set or parameter_set == "none":
        return "no parameter set: the model's own constants, nothing fitted to these rows"
    on = parameter_set_source(parameter_set)["fitted_on"]
    if not on.get("sha256"):
        return (f"parameter set {parameter_set} records no fleet file it was fitted on: whether these rows were in its "
                "fit is unknown") if is_parameter_set_file(parameter_set) else (
                f"parameter set {parameter_set}: constants not fitted to a fleet")
    if on["sha256"] == hashlib.sha256(Path(data).read_bytes()).hexdigest():
        return f"parameter set {parameter_set} was fitted on this file: in-sample"
    said = f"parameter set {parameter_set} was fitted on {on.get('path') or on.get('file')} (not this file)"
    where = [Path(str(w)) for w in (on.get("path"), on.get("file")) if w]
    where += [PARAMETER_SET_DIR.parents[2] / w for w in where if not w.is_absolute()]  # a shipped set's, in the tree
    if is_parameter_set_file(parameter_set):
        where += [Path(parameter_set).parent / w for w in where if not w.is_absolute()]
    fit_file = next((w for w in where if w.is_file() and hashlib.sha256(w.read_bytes()).hexdigest() == on["sha256"]),
                    None)
    if fit_file is None:
        return f"{said}, which is not at hand: whether these rows were in its fit is unknown"

    def rows(path):  # each data row as its cells by column name
        head, *body = read_csv_rows(path, "fleet file")
        return [dict(zip((h.strip() for h in head), (c.strip() for c in r))) for r in body if any(c.strip() for c in r)]

    ours = rows(data)
    by_cells, by_energy = training_cars(ours, rows(fit_file))
    if not (by_cells | by_energy).any():
        return f"{said}, which has none of these cars: held out"
    how = [f"{n} by {what}" for n, what in (
        (int(by_cells.sum()), "make, model and model inputs, whatever their measured energies and test labels"),
        (int((by_energy & ~by_cells).sum()), f"their measured UDDS and HWFET energies alone, within "
                                             f"{100 * SAME_CAR_REL:g} %")) if n]
    return (f"{said}; {int((by_cells | by_energy).sum())} of these {len(ours)} rows are cars in it "
            f"({'; '.join(how)}): in-sample for those")


# Two rows are one car within this relative difference of a number: re-typed cells (A rounded to 0.1 N, a test
# mass 1 kg off, energies typed to 0.1 Wh/km) differ by less; two distinct cars of the shipped fleet lie at least
# 0.5 % apart on UDDS or HWFET energy
SAME_CAR_REL = 1e-3


def training_cars(ours: list[dict], theirs: list[dict]) -> tuple[np.ndarray, np.ndarray]:
    """Which of the rows ``ours`` (cells by column name) are cars of the rows ``theirs``: per row of ``ours``,
    (its make, model and model inputs, every common cell but the measured energies, reported_unit, flag and the
    test's labels test_vehicle_id and config, match one row of ``theirs``: text blind to case, spaces and
    punctuation, numbers within ``SAME_CAR_REL``, so a copy in Wh/mi or a retest is the same car; its measured
    UDDS and HWFET energies both lie within ``SAME_CAR_REL`` of one row's, so a copy with a renamed test or a
    re-typed input is too). One numpy comparison of every pair of rows."""
    from bev_mdo.models.fleet import MEASURED

    energy = list(MEASURED.values())
    cols = sorted(set(ours[0] if ours else ()) & set(theirs[0] if theirs else ()) - set(energy)
                  - {"reported_unit", "flag", "test_vehicle_id", "config"})

    def table(rows, names):  # (numbers, nan where a cell is not one; text normalised, '' where it is a number)
        num = np.full((len(rows), len(names)), np.nan)
        text = np.full((len(rows), len(names)), "", object)
        for i, r in enumerate(rows):
            for j, k in enumerate(names):
                try:
                    num[i, j] = float(r.get(k) or "")
                except ValueError:
                    text[i, j] = "".join(ch for ch in (r.get(k) or "").casefold() if ch.isalnum())
        return num, text

    def close(a, b, blank_same):  # (n, m): every column of row i of a within SAME_CAR_REL of row j of b
        a, b = a[:, None, :], b[None, :, :]
        with np.errstate(invalid="ignore"):
            near = np.abs(a - b) <= SAME_CAR_REL * np.maximum(np.abs(a), np.abs(b))
        return (near | (blank_same & np.isnan(a) & np.isnan(b))).all(axis=2)

    (num_o, text_o), (num_t, text_t) = table(ours, cols), table(theirs, cols)
    by_cells = (close(num_o, num_t, True) & (text_o[:, None, :] == text_t[None, :, :]).all(axis=2)).any(axis=1)
    by_energy = close(table(ours, energy)[0], table(theirs, energy)[0], False).any(axis=1)
    return by_cells, by_energy


REFERENCE = {"baseline3": "3-constant baseline a + b mass + c road-load work per cycle, each family predicted by "
                          "constants fitted on the other folds ({k}-fold by family)",
             "fastsim": "FASTSim 2.1.5 with its defaults (bev_mdo/data/epa_2022_bev/fastsim_2.1.5.csv, "
                        "scripts/fastsim_baseline.py)"}


def _reference(fleet, energy_model: str, pred: dict, scored: dict, out_rows: list, pairs: dict | None,
               cycles: dict, compared_text: str) -> dict:
    """The model beside the 3-constant baseline and FASTSim on the same rows (models/baselines.py);
    adds each row's baseline and FASTSim prediction to ``out_rows`` (None where there is none).
    ``compared_text``: what the model's column compares (:func:`compared` with the run's parameter set)."""
    from bev_mdo.models import baselines as bl, fleet as fl, pairs as pr

    use = ~fleet.outlier & np.logical_and.reduce([scored[c] for c in fl.CYCLES])
    columns = {energy_model: {c: np.where(scored[c], pred[c]["energy_wh_per_km"], np.nan) for c in fl.CYCLES},
               "baseline3": bl.three_constant_cv(fleet, use, cycles)}
    three = columns["baseline3"]
    baseline3 = "available" if any(np.isfinite(three[c]).any() for c in fl.CYCLES) else (
        "none: its 3 constants per cycle need rows of other model families (one family, or too few rows)")
    fastsim = bl.read_fastsim(fleet)
    if fastsim is None:
        status = f"unavailable: {bl.FASTSIM_CSV} is missing"
    elif not any(np.isfinite(fastsim[c]).any() for c in fl.CYCLES):
        status = "unavailable: FASTSim was not run on this fleet file (scripts/fastsim_baseline.py --data CSV)"
    else:
        run = int(np.logical_or.reduce([np.isfinite(fastsim[c]) for c in fl.CYCLES]).sum())
        status = "available" if run == len(fleet) else (
            f"run on {run} of {len(fleet)} rows (the others are not in its file or their inputs differ)")
        columns["fastsim"] = fastsim
    for r, i in zip(out_rows, range(len(fleet))):
        for c in fl.CYCLES:
            short = c.replace("epa_", "")
            for name in ("baseline3", "fastsim"):
                v = columns[name][c][i] if name in columns else math.nan
                r[f"{short}_{name}_wh_per_km"] = float(v) if math.isfinite(v) else None
    if baseline3 != "available":  # no figure at all: the others are scored on their own rows, not on none
        del columns["baseline3"]
    folds = int(bl.family_folds(fleet, use).max()) + 1  # as many as the families, up to baselines.FOLDS
    out = {"columns": {energy_model: compared_text, **REFERENCE,
                       "baseline3": REFERENCE["baseline3"].format(k=folds)},
           "fastsim": status, "baseline3": baseline3, "same_rows": bl.reference_table(fleet, columns),
           "baseline3_folds": folds}
    if pairs is not None:
        index = {int(row): i for i, row in enumerate(fleet.rows)}
        out["pairs"] = {}
        for name in [n for n in ("baseline3", "fastsim") if n in columns]:
            out["pairs"][name] = {}
            for c in fl.CYCLES:
                short = c.replace("epa_", "")
                ok = [(index[r["a_row"]], index[r["b_row"]]) for r in pairs[short]["rows"]]
                ok = [(a, b) for a, b in ok if np.isfinite(columns[name][c][[a, b]]).all()]
                out["pairs"][name][short] = pr.pair_stats(pr.pct_diff(fleet.measured[c], ok),
                                                          pr.pct_diff(columns[name][c], ok))
    return out


def _pairs(fleet, pred: dict, scored: dict) -> dict:
    """Within-family pairs per cycle: a pair counts on a cycle when both vehicles are scored there."""
    from bev_mdo.models import fleet as fl, pairs as pr

    family = fleet.model_line()
    all_pairs = pr.find_pairs(family, fleet.drive, fleet.rated_power_kw, fleet.test_mass_kg, ~fleet.outlier)
    out = {"rule": "same make and model line (Fleet.model_line), different drive class, rated power or test mass; "
                   "A = earlier row, diff = 200 (E_B - E_A) / (E_A + E_B)",
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
    report = evaluate(args.data, args.energy_model, args.parameter_set, pairs=args.pairs)
    if args.plot:
        from bev_mdo.cli.validate_plots import write_all

        write_all(report, args.plot)
    if args.json:
        print(jsontext.dumps(report))
    else:
        print_table(report)
        if args.pairs:
            print_pairs(report)
        print_reference(report)
    return 0


def _f(x, nd=1):
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def print_table(report: dict) -> None:
    ps = f", parameter set {report['parameter_set']}" if report.get("parameter_set") else ""
    n = report["vehicles"]
    print(f"{report['data']}: {n} vehicle{'' if n == 1 else 's'}, energy model {report['energy_model']}{ps}; "
          f"Wh/km, {report['compared']}")
    print(f"{'row':>4} {'make':10} {'model':34} {'kg':>6} {'kW':>5} | {'UDDS meas':>9} {'pred':>7} {'err%':>6} | "
          f"{'HWFET meas':>10} {'pred':>7} {'err%':>6}")
    for r in report["rows"]:
        cells = []
        for c, w in (("udds", 9), ("hwfet", 10)):
            note = "" if r[f"{c}_follows"] else " CANNOT FOLLOW"
            cells.append(f"{r[f'{c}_measured_wh_per_km']:>{w}.1f} {r[f'{c}_predicted_wh_per_km']:>7.1f} "
                         f"{r[f'{c}_error_pct']:>+6.1f}{note}")
        flag = " (outlier, not scored)" if r["outlier"] else ""
        print(f"{r['row']:>4} {r['make'][:10]:10} {r['model'][:34]:34} {r['test_mass_kg']:>6.0f} "
              f"{r['rated_power_kw']:>5.0f} | {cells[0]} | {cells[1]}{flag}")
    for name, s in report["stats"].items():
        print(f"{name:>11}: n={s['n']:3d}  mean |err| {_f(s['mean_abs_pct'], 2)} %  median {_f(s['median_abs_pct'], 2)} %"
              f"  P90 {_f(s['p90_abs_pct'], 2)} %  max {_f(s['max_abs_pct'], 2)} %"
              f"  mean signed {_f(s['mean_signed_pct'], 2)} %")
    if report.get("by_make") and len(report["by_make"]) > 1:
        print("by make, both cycles (mean signed % / mean |err| %): " + ", ".join(
            f"{r['make']} {r['mean_signed_pct']:+.1f} / {r['mean_abs_pct']:.1f}" for r in report["by_make"]))
    if report["not_following"]:
        print(f"{len(report['not_following'])} vehicle-cycle(s) whose rated power cannot follow the cycle "
              f"(not scored): " + ", ".join(f"row {x['row']} {x['cycle']}" for x in report["not_following"]))



def _met(flag) -> str:
    return "-" if flag is None else ("met" if flag else "NOT met")


def print_pairs(report: dict) -> None:
    pairs = report["pairs"]
    if not pairs["pairs"]:
        print(f"pairs: none in {report['data']} (no two rows of one model family differ in drive, "
              f"rated power or test mass)")
        return
    print(f"within-family pairs ({pairs['pairs']} pairs in {pairs['families']} families; meas% and pred%: "
          "200 (E_B - E_A) / (E_A + E_B), B minus A in percent of the pair's mean; diff = pred% - meas%, points; "
          "slope by least squares through the origin):")
    print(f"{'cycle':6} {'A row':>5} {'B row':>5} {'A model':30} {'B model':30} {'meas%':>7} {'pred%':>7} "
          f"{'diff':>6}")
    for c in ("udds", "hwfet"):
        for r in pairs[c]["rows"]:
            print(f"{c:6} {r['a_row']:>5} {r['b_row']:>5} {r['a_model'][:30]:30} {r['b_model'][:30]:30} "
                  f"{r['measured_pct']:>+7.1f} {r['predicted_pct']:>+7.1f} "
                  f"{r['predicted_pct'] - r['measured_pct']:>+6.1f}")
    for c in ("udds", "hwfet"):
        s = pairs[c]
        lo, hi = s["slope_target"]
        print(f"pairs {c:>5}: n={s['n']:3d}  slope {_f(s['slope_through_origin'], 2)} (target {lo}-{hi}: "
              f"{_met(s['slope_met'])})  mean |diff| {_f(s['mean_abs_diff_points'], 2)} points "
              f"(target <= {s['mean_abs_diff_target_points']}: {_met(s['mean_abs_diff_met'])})")


def print_reference(report: dict) -> None:
    """The model beside the 3-constant baseline and FASTSim, per cycle, on the rows every column scores."""
    ref = report["reference"]
    names = [n for n in ref["same_rows"]["udds"] if n not in ("rows", "pairs")]
    three = "" if ref.get("baseline3", "available") == "available" else f"; baseline3: {ref['baseline3']}"
    print(f"beside the references, same rows (FASTSim: {ref['fastsim']}{three}); MAPE %, pair slope, pair mean "
          "|diff| points:")
    for c in ("udds", "hwfet"):
        t = ref["same_rows"][c]
        cells = "; ".join(f"{n} {_f(t[n]['mape_pct'], 2)} / {_f(t[n]['pair_slope'], 2)} / "
                          f"{_f(t[n]['pair_mad_points'], 2)}" for n in names)
        print(f"{c:>6} ({t['rows']} rows, {t['pairs']} pairs): {cells}" if t["rows"] else
              f"{c:>6}: no row that every column predicts (baseline3 is held out by family: a row needs rows "
              "of other families that fix its 3 constants)")
    folds = ref["baseline3_folds"]
    three = (f"held out, {folds} fold{'' if folds == 1 else 's'} by family"
             if ref.get("baseline3", "available") == "available" else "none")
    print(f"  ({report['energy_model']}: as above, not refitted: {report['parameter_set_fitted_on']}; baseline3: "
          f"{three}; fastsim: its defaults, nothing fitted; held-out figures of every model: bench/bench_validate.py, "
          "docs/validation.md)")
