"""Speed of the flat energy model (and acceleration) on the 1 Hz NEDC. Prints its figures."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bev_mdo.models.acceleration import accel_time_0_100_s
from bev_mdo.models.cycles import nedc, resample
from bev_mdo.models.flat import energy_wh_per_km, energy_wh_per_km_direct


def best_of(fn, repeat=20):
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return min(ts), float(np.median(ts))


def measure(r, p, m, g, rng, n) -> dict:
    """One run of every figure (seconds or designs/s)."""
    best, med = best_of(lambda: energy_wh_per_km(r, p, m, g))
    out = {"flat_batch": n / med}
    one_m, one_g = m[:1], g[:1]
    ts = []
    for _ in range(5000):
        t0 = time.perf_counter()
        energy_wh_per_km(r, p, one_m, one_g)
        ts.append(time.perf_counter() - t0)
    out["flat_one"] = float(np.median(ts))
    best, med = best_of(lambda: energy_wh_per_km_direct(r, p, m, g), repeat=3)
    out["direct_batch"] = n / med
    mk = rng.uniform(40, 120, n)
    best, med = best_of(lambda: accel_time_0_100_s(mk, g, m))
    out["accel_batch"] = n / med
    return out


def main():
    import argparse

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _results

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=5, help="repetitions of the whole measurement (median and range)")
    ap.add_argument("--json", default=None, help="results file (default bench/results/models.json)")
    args = ap.parse_args()
    r = resample(nedc(), 1.0, "pchip")
    rng = np.random.default_rng(0)
    n = 10_000
    m, g = rng.uniform(1400, 1800, n), rng.uniform(1, 11, n)
    p = {}
    energy_wh_per_km(r, p, m, g)  # warm the moment cache (precomputed once per cycle)
    t0 = time.perf_counter()
    from bev_mdo.models import flat
    flat._MOMENTS.clear()
    energy_wh_per_km(r, p, m[:1], g[:1])
    t_pre = time.perf_counter() - t0
    runs = [measure(r, p, m, g, rng, n) for _ in range(max(1, args.runs))]
    col = {k: [x[k] for x in runs] for k in runs[0]}
    figs = [
        _results.figure(f"flat-model energy, {n} designs on 1 Hz NEDC, one call", "designs/s", col["flat_batch"],
                        ">= 100000"),
        _results.figure("flat-model energy, one design", "µs", [v * 1e6 for v in col["flat_one"]], "<= 100"),
        _results.figure(f"flat-model energy as a direct time-series sum, {n} designs", "designs/s", col["direct_batch"]),
        _results.figure(f"0-100 km/h time, {n} designs", "designs/s", col["accel_batch"]),
        _results.figure("flat-model cycle moments, precomputed once per cycle", "ms", [t_pre * 1e3]),
    ]
    for f in figs:
        print(f"{f['what']}: median {f['median']:,.4g} {f['unit']} (range {f['min']:,.4g}-{f['max']:,.4g}, "
              f"{len(f['runs'])} runs)")
    _results.write("models", figs, path=args.json)


if __name__ == "__main__":
    main()
