"""Tables and plots of ``bev-mdo sensitivity --global sobol|morris`` (the indices: bev_mdo.api.sensitivity)."""
from __future__ import annotations

import numpy as np
from bev_mdo.figures import styled, subplots


def print_tables(rep: dict) -> None:
    names = rep["variables"]
    w = max(12, *(len(n) for n in names)) + 2
    fixed = rep["fixed"]
    print(f"global sensitivity ({rep['method']}, N = {rep['samples']}, seed {rep['seed']}, "
          f"{rep['n_evaluations']} designs in one batch, {100 * rep['conf_level']:g} % confidence)")
    print("over " + ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in rep["bounds"].items()))
    if fixed:
        print("fixed at " + ", ".join(f"{k}={v:g}" for k, v in fixed.items()))
    keys = (("S1", "S1_conf"), ("ST", "ST_conf")) if rep["method"] == "sobol" else (("mu_star", "mu_star_conf"), ("sigma", None))
    units = rep.get("units") or {}
    for out_name, r in rep["outputs"].items():
        unit = units.get(out_name, "").strip()
        # Morris' mu* and sigma are in the output's unit (per the variable's whole range); Sobol' indices are shares
        print(f"\n{out_name}" + (f" (mu* and sigma in {unit})" if rep["method"] == "morris" and unit not in
                                  ("", "1", "-") else ""))
        if r.get("constant"):
            print("  constant over these bounds (or not finite): no indices")
            continue
        rows = [(key, [f" {v:.4g}" + (f" ±{c:.2g}" if conf else "") for v, c in
                       zip(r[key], r[conf] if conf else [0] * len(names))]) for key, conf in keys]
        width = max(w, *(len(c) + 2 for _, cells in rows for c in cells))  # a column as wide as its widest cell
        print("".ljust(10) + "".join(n.rjust(width) for n in names))
        for key, cells in rows:
            print(key.ljust(10) + "".join(c.rjust(width) for c in cells))
    for note in rep.get("notes", ()):
        print(f"\nnote: {note}")


@styled
def write_plot(path: str, rep: dict) -> None:
    """Bars of the indices of every output with their confidence intervals; the title names the
    bounds, the fixed values, N and the seed."""
    from bev_mdo.api.evaluate import axis_label
    from bev_mdo.cli import save_figure

    label = axis_label(rep.get("units"))
    names, outs = rep["variables"], [k for k, r in rep["outputs"].items() if not r.get("constant")]
    keys = (("S1", "S1_conf", "first order S1"), ("ST", "ST_conf", "total ST")) if rep["method"] == "sobol" \
        else (("mu_star", "mu_star_conf", "mu* (output unit)"), ("sigma", None, "sigma (output unit)"))
    fig, axes = subplots(1, max(len(outs), 1), figsize=(3.2 + 2.6 * max(len(outs), 1), 4.2),
                             squeeze=False, layout="constrained")
    xs = np.arange(len(names))
    for ax, out in zip(axes[0], outs):
        r = rep["outputs"][out]
        for k, (key, conf, lab) in enumerate(keys):
            err = np.asarray(r[conf]) if conf else None
            ax.bar(xs + (k - 0.5) * 0.38, r[key], 0.38, yerr=err, capsize=2, label=lab)
        ax.set_xticks(xs, [label(v) for v in names], rotation=25, ha="right", fontsize=7)
        ax.set_title(label(out), fontsize=9)
        ax.axhline(0, color="k", lw=0.6)
        ax.grid(axis="y", alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fixed = ", ".join(f"{k}={v:g}" for k, v in rep["fixed"].items())
    fig.suptitle(f"{rep['method']} indices over the bounds (N = {rep['samples']}, seed {rep['seed']}, "
                 f"{100 * rep['conf_level']:g} % intervals)" + (f"\nfixed at {fixed}" if fixed else ""), fontsize=9)
    save_figure(fig, path)
