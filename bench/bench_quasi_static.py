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


def main(n: int = 1000) -> None:
    cyc = resample(load_cycle("nedc"), 1.0)
    rng = np.random.default_rng(0)
    m = rng.uniform(1400, 1800, n)
    ig = rng.uniform(6, 10, n)
    kw = rng.uniform(60, 120, n)
    kwh = rng.uniform(20, 40, n)
    quasi_static.default_map()  # load the CSV once
    t = best_of(lambda: quasi_static.energy_wh_per_km(cyc, {}, m, ig, kw, battery_kwh=kwh))
    print(f"quasi-static energy, NEDC 1 Hz, N={n}: {t * 1e3:.1f} ms, {n / t:,.0f} designs/s")
    t1 = best_of(lambda: quasi_static.energy_wh_per_km(cyc, {}, 1590.0, 7.94, 80.0), repeats=5)
    print(f"quasi-static energy, one design: {t1 * 1e3:.2f} ms")
    k = min(n, 100)
    t2 = best_of(lambda: quasi_static.range_by_repeated_cycle_km(cyc, {}, m[:k], ig[:k], kw[:k], kwh[:k]), 1)
    print(f"quasi-static range (repeat NEDC 100 % -> 5 % SOC), N={k}: {t2:.2f} s, {k / t2:,.0f} designs/s")
    nb = 10 * n
    mb = rng.uniform(1400, 1800, nb)
    t3 = best_of(lambda: breakdown.energy_wh_per_km(cyc, {}, mb, 8.0, 80.0))
    print(f"chapter-5 breakdown, N={nb}: {t3 * 1e3:.2f} ms, {nb / t3:,.0f} designs/s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 1000)
