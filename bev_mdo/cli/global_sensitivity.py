"""Global sensitivity over the design variables' bounds: ``bev-mdo sensitivity --global sobol|morris``.

SALib draws the designs and estimates the indices; every design is evaluated in ONE batch (one
evaluator call: in process, or one request wave per graph level over ROS).

* ``sobol``: Saltelli's sampling of Sobol' sequences, N (D + 2) designs for D variables; first-order
  (S1) and total (ST) Sobol' indices of every output, each with its bootstrap confidence interval.
* ``morris``: N trajectories of D + 1 designs on a 4-level grid; mu* (the mean absolute elementary
  effect, in the output's unit) with its confidence interval, and sigma (interactions and
  non-linearity).
Variables not analysed (and model parameters) keep their value at the design point (``--at``).
"""
from __future__ import annotations

import numpy as np

from bev_mdo.cli import UsageError

METHODS = ("sobol", "morris")


def analyse(method: str, fun, point: dict, bounds: dict[str, tuple[float, float]], names: list[str],
            outputs: list[str], samples: int, seed: int, conf_level: float = 0.95,
            num_resamples: int = 1000, design: list[str] | None = None) -> dict:
    """The indices of every output (JSON-ready). ``fun(X)`` evaluates rows of every column of
    ``point`` and returns {output: values}; it is called once, with every design. ``design``: the
    design variables (those not analysed are reported as fixed; default: every name of ``point``)."""
    if method not in METHODS:
        raise UsageError(f"--global {method!r}: allowed: {', '.join(METHODS)}")
    if not names:
        raise UsageError("--global: no design variable to analyse")
    missing = [k for k in names if k not in bounds]
    if missing:
        raise UsageError(f"--global: {missing[0]!r} has no bounds (only design variables can be analysed globally)")
    if samples < 2:
        raise UsageError(f"--samples {samples}: must be >= 2")
    if not 0 < conf_level < 1:
        raise UsageError(f"--conf-level {conf_level}: must be in (0, 1)")
    spec = {"num_vars": len(names), "names": list(names), "bounds": [list(map(float, bounds[k])) for k in names]}
    if method == "sobol":
        from SALib.sample import sobol as sampler

        m = int(round(np.log2(samples)))
        if 2 ** m != samples:
            raise UsageError(f"--global sobol --samples {samples}: must be a power of 2 (e.g. {2 ** m} or "
                             f"{2 ** (m + 1)}) for the Sobol' sequence's balance")
        X = sampler.sample(spec, samples, calc_second_order=False, scramble=True, seed=seed)
    else:
        from SALib.sample import morris as sampler

        X = sampler.sample(spec, samples, num_levels=4, seed=seed)
    cols = list(point)
    full = np.tile(np.array([point[k] for k in cols], dtype=float), (len(X), 1))
    for j, k in enumerate(names):
        full[:, cols.index(k)] = X[:, j]
    values = fun(full)
    report = {"method": method, "variables": list(names), "bounds": {k: list(bounds[k]) for k in names},
              "fixed": {k: float(point[k]) for k in (design if design is not None else point) if k not in names},
              "samples": samples, "seed": seed,
              "conf_level": conf_level, "n_evaluations": int(len(X)), "outputs": {}}
    for out in outputs:
        y = np.asarray(values[out], dtype=float)
        if not np.isfinite(y).all() or np.ptp(y) == 0.0:
            report["outputs"][out] = {"constant": True}
            continue
        if method == "sobol":
            from SALib.analyze import sobol

            r = sobol.analyze(spec, y, calc_second_order=False, num_resamples=num_resamples,
                              conf_level=conf_level, seed=seed)
            report["outputs"][out] = {k: np.asarray(r[k], float).tolist() for k in ("S1", "S1_conf", "ST", "ST_conf")}
        else:
            from SALib.analyze import morris

            r = morris.analyze(spec, X, y, num_resamples=num_resamples, conf_level=conf_level, num_levels=4, seed=seed)
            report["outputs"][out] = {k: np.asarray(r[k], float).tolist() for k in ("mu", "mu_star", "mu_star_conf", "sigma")}
    return report


def print_tables(rep: dict, out) -> None:
    names = rep["variables"]
    w = max(12, *(len(n) for n in names)) + 2
    fixed = rep["fixed"]
    print(f"global sensitivity ({rep['method']}, N = {rep['samples']}, seed {rep['seed']}, "
          f"{rep['n_evaluations']} designs in one batch, {100 * rep['conf_level']:g} % confidence)", file=out)
    print("over " + ", ".join(f"{k} in [{lo:g}, {hi:g}]" for k, (lo, hi) in rep["bounds"].items()), file=out)
    if fixed:
        print("fixed at " + ", ".join(f"{k}={v:g}" for k, v in fixed.items()), file=out)
    keys = (("S1", "S1_conf"), ("ST", "ST_conf")) if rep["method"] == "sobol" else (("mu_star", "mu_star_conf"), ("sigma", None))
    for out_name, r in rep["outputs"].items():
        print(f"\n{out_name}", file=out)
        if r.get("constant"):
            print("  constant over these bounds (or not finite): no indices", file=out)
            continue
        print("".ljust(10) + "".join(n.rjust(w) for n in names), file=out)
        for key, conf in keys:
            cells = [f" {v:.4g}" + (f" ±{c:.2g}" if conf else "") for v, c in
                     zip(r[key], r[conf] if conf else [0] * len(names))]
            print(key.ljust(10) + "".join(c.rjust(w) for c in cells), file=out)


def write_plot(path: str, rep: dict) -> None:
    """Bars of the indices of every output with their confidence intervals; the title names the
    bounds, the fixed values, N and the seed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bev_mdo.cli import figure_format
    from bev_mdo.mdo import units as un

    def label(name):
        return un.label(name, rep.get("units") or {})

    names, outs = rep["variables"], [k for k, r in rep["outputs"].items() if not r.get("constant")]
    keys = (("S1", "S1_conf", "first order S1"), ("ST", "ST_conf", "total ST")) if rep["method"] == "sobol" \
        else (("mu_star", "mu_star_conf", "mu* (output unit)"), ("sigma", None, "sigma (output unit)"))
    fig, axes = plt.subplots(1, max(len(outs), 1), figsize=(3.2 + 2.6 * max(len(outs), 1), 4.2),
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
    fig.savefig(path, dpi=110, format=figure_format(path))
    plt.close(fig)
