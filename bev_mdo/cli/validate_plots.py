"""Plots of ``bev-mdo validate --plot DIR``: the parity and residual plot (``parity.png``) and, with
``--pairs``, one arrow plot per cycle (``pairs_udds.png``, ``pairs_hwfet.png``): each within-family
pair is an arrow from variant A to variant B in measured-against-predicted energy, one panel per
model column (the chosen model, the 3-constant baseline, FASTSim 2.1.5). A model that moves with the
design as the cars do draws arrows parallel to y = x; a model that under-predicts the change draws
them flatter, a wrong sign points them down where the cars went up. matplotlib, Agg backend.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from bev_mdo.cli import save_figure
from bev_mdo.figures import colormap, styled, subplots


def _f(x, nd=1) -> str:  # as validate's table (not imported: validate imports this module)
    return "-" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{x:.{nd}f}"


def write_all(report: dict, directory) -> list[Path]:
    """Write the plots into ``directory`` (created if missing; ValueError naming it if it is a file)."""
    d = Path(directory)
    if d.exists() and not d.is_dir():
        raise ValueError(f"--plot {directory}: not a directory (give a folder; the plots are written into it)")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"--plot {directory}: cannot create the folder: {exc.strerror}") from None
    written = [d / "parity.png"]
    plot(report, written[0])
    if "pairs" in report:
        for c in ("udds", "hwfet"):
            written.append(d / f"pairs_{c}.png")
            plot_pair_arrows(report, c, written[-1])
    return written


@styled
def plot(report: dict, path: str) -> None:
    """Parity plot with the +-5 % band, residuals against test mass and rated power."""
    rows = report["rows"]
    fig, ax = subplots(1, 3, figsize=(15, 5.4))
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
              ylabel=f"predicted {'wall' if 'predicted wall energy' in report['compared'] else 'battery'} energy "
                     "(Wh/km)")
    s = report["stats"]["udds_hwfet"]
    ax[0].text(0.02, 0.98, f"mean |err| {_f(s['mean_abs_pct'], 2)} %\nP90 {_f(s['p90_abs_pct'], 2)} %",
               transform=ax[0].transAxes, va="top")
    for a, xl in ((ax[1], "test mass (kg)"), (ax[2], "rated power (kW)")):
        a.axhspan(-5, 5, color="grey", alpha=0.2)
        a.axhline(0, color="k", lw=1)
        a.set(xlabel=xl, ylabel="error %", title=f"residual vs {xl.split(' (')[0]}")
    for a in ax:  # under the axes: inside, one covered the worst points (an Audi e-tron S at 2948 kg)
        a.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=4, fontsize=8, frameon=False)
        a.grid(alpha=0.3)
    fig.suptitle(f"{report['energy_model']} on {report['data'].rsplit('/', 1)[-1]}")
    _save(fig, path)


@styled
def plot_pair_arrows(report: dict, cycle: str, path) -> None:
    """One panel per model column: every pair of the cycle as an arrow from (measured A, predicted A)
    to (measured B, predicted B), Wh/km, with y = x; the title gives the pair slope and mean
    absolute difference of that column."""
    by_row = {r["row"]: r for r in report["rows"]}
    pairs = report["pairs"][cycle]["rows"]
    columns = [(report["energy_model"], "predicted", report["pairs"][cycle])]
    for name, label in (("baseline3", "3-constant baseline (held out)"), ("fastsim", "FASTSim 2.1.5 defaults")):
        ref = report["reference"]["pairs"].get(name, {}).get(cycle)
        if ref is not None:
            columns.append((label, name, ref))
    fig, axes = subplots(1, len(columns), figsize=(5.2 * len(columns), 5.0), squeeze=False)
    families = list(dict.fromkeys(p["family"] for p in pairs))
    colour = {f: colormap("tab20")(i % 20) for i, f in enumerate(families)}
    lo, hi = math.inf, 0.0
    for ax, (label, key, stats) in zip(axes[0], columns):
        n = 0
        for p in pairs:
            a, b = by_row[p["a_row"]], by_row[p["b_row"]]
            xa, xb = a[f"{cycle}_measured_wh_per_km"], b[f"{cycle}_measured_wh_per_km"]
            ya, yb = a.get(f"{cycle}_{key}_wh_per_km"), b.get(f"{cycle}_{key}_wh_per_km")
            if ya is None or yb is None:
                continue
            ax.annotate("", xy=(xb, yb), xytext=(xa, ya),
                        arrowprops={"arrowstyle": "->", "color": colour[p["family"]], "alpha": 0.7, "lw": 1})
            lo, hi = min(lo, xa, xb, ya, yb), max(hi, xa, xb, ya, yb)
            n += 1
        ax.set_title(f"{label}: {n} pairs\nslope {_f(stats['slope_through_origin'], 2)}, "
                     f"mean |diff| {_f(stats['mean_abs_diff_points'], 2)} points", fontsize=10)
    if not math.isfinite(lo):
        lo, hi = 50.0, 300.0
    lim = (lo * 0.95, hi * 1.05)
    for ax in axes[0]:
        ax.plot(lim, lim, "k-", lw=1, label="y = x")
        ax.set(xlim=lim, ylim=lim, xlabel="measured wall energy (Wh/km)", ylabel="predicted energy (Wh/km)")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    for f in families:  # one colour per model line
        axes[0][0].plot([], [], color=colour[f], label=f)
    for ax in axes[0]:
        ax.legend(loc="upper left", fontsize=7 if ax is axes[0][0] else 8)
    fig.suptitle(f"within-family pairs on {cycle.upper()}, arrow from variant A to variant B "
                 f"({report['data'].rsplit('/', 1)[-1]})")
    _save(fig, path)


def _save(fig, path) -> None:
    """Write a figure (format from the name) and close it; an unwritable path is one ValueError."""
    fig.tight_layout()
    save_figure(fig, path)

