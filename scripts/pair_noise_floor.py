"""What would a perfect model score on the within-family pairs? (docs/validation.md "Ceiling of the pairs")

The pair figures compare a model's percentage differences between two variants with the measured
ones. The measured ones carry the test-to-test scatter of two dynamometer tests, so even a model
that predicted every true difference exactly would not score slope 1 and difference 0:

* the slope through the origin of predicted on measured, sum(x y) / sum(x^2), is attenuated: with
  x = t + e (t true, e scatter of variance s^2, independent of t) and y = t, its expectation is about
  (sum(x^2) - n s^2) / sum(x^2);
* the mean absolute difference |y - x| = |e| has the expectation mean |e|.

The scatter is estimated from the fleet's **couples**: two rows of one model line with the same
drive class, rated power and test mass (so not a pair), which differ only in wheels or trim, hence
in the measured road load the models read. A model's residual on a couple is the scatter plus its
error on a road-load change, so s^2 from couples is an upper bound: the perfect model's slope
below is a lower bound and its difference an upper bound.

    PYTHONPATH=. python scripts/pair_noise_floor.py [--models quasi_static chain]

A research tool, not shipped.
"""
from __future__ import annotations

import argparse

import numpy as np

from bev_mdo.models import fleet as fl
from bev_mdo.models import pairs as pr


def couples(fleet: fl.Fleet) -> list[tuple[int, int]]:
    """Every (a, b), a < b, of usable rows in one model line that :func:`pairs.find_pairs` leaves out:
    the same drive class, rated power and test mass."""
    line, ok = fleet.model_line(), ~fleet.outlier
    pairs = set(pr.find_pairs(line, fleet.drive, fleet.rated_power_kw, fleet.test_mass_kg, ok))
    return [(a, b) for a in range(len(fleet)) for b in range(a + 1, len(fleet))
            if ok[a] and ok[b] and line[a] == line[b] and (a, b) not in pairs]


def perfect_model(measured_pct: np.ndarray, scatter_pct: np.ndarray) -> dict:
    """Expected pair figures of a model with no error, given the measured pair differences and
    samples of the measurement scatter of a difference (points)."""
    x, e = np.asarray(measured_pct, float), np.asarray(scatter_pct, float)
    s2 = float(np.mean(e ** 2))
    sxx = float(np.dot(x, x))
    return {"scatter_rms_points": s2 ** 0.5, "slope": (sxx - x.size * s2) / sxx,
            "mean_abs_diff_points": float(np.mean(np.abs(e)))}


def main(argv=None) -> int:
    from bev_mdo.cli.validate import DEFAULT_SETS
    from bev_mdo.models.params import load_parameter_set

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=["quasi_static", "chain"])
    args = ap.parse_args(argv)
    fleet = fl.read_fleet()
    pairs = pr.find_pairs(fleet.model_line(), fleet.drive, fleet.rated_power_kw, fleet.test_mass_kg, ~fleet.outlier)
    cps = couples(fleet)
    print(f"{len(pairs)} pairs, {len(cps)} couples (same drive, rated power and mass: wheels or trim)")
    print("model         cycle  couples: rms / mean |res|  | perfect model: slope, mean |diff|  | this model (training fit)")
    for model in args.models:
        pred = fl.predict(fleet, model, load_parameter_set(DEFAULT_SETS[model]))
        for c in fl.CYCLES:
            meas, e = fleet.measured[c], pred[c]["energy_wh_per_km"]
            res = pr.pct_diff(e, cps) - pr.pct_diff(meas, cps)
            x = pr.pct_diff(meas, pairs)
            best = perfect_model(x, res)
            got = pr.pair_stats(x, pr.pct_diff(e, pairs))
            print(f"{model:13s} {c[4:]:6s} {best['scatter_rms_points']:8.2f} / {np.mean(np.abs(res)):5.2f}"
                  f"             | {best['slope']:5.3f}, {best['mean_abs_diff_points']:5.2f}"
                  f"                    | {got['slope_through_origin']:5.3f}, {got['mean_abs_diff_points']:5.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
