"""Benchmark: quasi-static map model (and the chapter-5 breakdown) on the 1 Hz NEDC.

Run: .venv/bin/python bench/bench_quasi_static.py [N]. Prints designs/s; not a test."""
from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bev_mdo.models import breakdown, quasi_static  # noqa: E402
from bev_mdo.models.cycles import load_cycle, resample  # noqa: E402


def best_of(fn, repeats=3):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def measure(n: int, cyc, rng) -> dict:
    m = rng.uniform(1400, 1800, n)
    ig = rng.uniform(6, 10, n)
    kw = rng.uniform(60, 120, n)
    kwh = rng.uniform(20, 40, n)
    out = {}
    t = best_of(lambda: quasi_static.energy_wh_per_km(cyc, {}, m, ig, kw, battery_kwh=kwh))
    out["qs_batch"] = n / t
    out["qs_one"] = best_of(lambda: quasi_static.energy_wh_per_km(cyc, {}, 1590.0, 7.94, 80.0), repeats=5)
    k = min(n, 100)
    t2 = best_of(lambda: quasi_static.range_by_repeated_cycle_km(cyc, {}, m[:k], ig[:k], kw[:k], kwh[:k]), 1)
    out["qs_range"] = k / t2
    nb = 10 * n
    mb = rng.uniform(1400, 1800, nb)
    out["breakdown"] = nb / best_of(lambda: breakdown.energy_wh_per_km(cyc, {}, mb, 8.0, 80.0))
    return out


def main() -> None:
    import argparse

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _results

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("n", nargs="?", type=int, default=1000)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", default=None, help="results file (default bench/results/quasi_static.json)")
    args = ap.parse_args()
    n = args.n
    cyc = resample(load_cycle("nedc"), 1.0)
    rng = np.random.default_rng(0)
    quasi_static.default_map()  # load the CSV once
    runs = [measure(n, cyc, rng) for _ in range(max(1, args.runs))]
    col = {k: [x[k] for x in runs] for k in runs[0]}
    k = min(n, 100)
    figs = [_results.figure(f"quasi-static map model energy, {n} designs on 1 Hz NEDC", "designs/s", col["qs_batch"]),
            _results.figure("quasi-static map model energy, one design", "ms", [v * 1e3 for v in col["qs_one"]]),
            _results.figure(f"quasi-static range by repeated NEDC (100 % -> 5 % SOC), {k} designs", "designs/s",
                            col["qs_range"]),
            _results.figure(f"chapter-5 breakdown energy, {10 * n} designs", "designs/s", col["breakdown"])]
    for f in figs:
        print(f"{f['what']}: median {f['median']:,.4g} {f['unit']} (range {f['min']:,.4g}-{f['max']:,.4g}, "
              f"{len(f['runs'])} runs)")
    _results.write("quasi_static", figs, path=args.json)


if __name__ == "__main__":
    main()
