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


def main():
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
    best, med = best_of(lambda: energy_wh_per_km(r, p, m, g))
    print(f"flat energy, {n} designs, 1 Hz NEDC, one call: median {med*1e3:.2f} ms "
          f"-> {n/med:,.0f} designs/s (best {n/best:,.0f})")
    one_m, one_g = m[:1], g[:1]
    reps = 5000
    ts = []
    for _ in range(reps):
        t0 = time.perf_counter()
        energy_wh_per_km(r, p, one_m, one_g)
        ts.append(time.perf_counter() - t0)
    print(f"flat energy, one design: median {np.median(ts)*1e6:.1f} us over {reps} calls")
    print(f"flat moments precompute (once per cycle and road constants): {t_pre*1e3:.2f} ms")
    best, med = best_of(lambda: energy_wh_per_km_direct(r, p, m, g), repeat=3)
    print(f"flat energy direct time-series sum, {n} designs: median {med*1e3:.0f} ms -> {n/med:,.0f} designs/s")
    mk = rng.uniform(40, 120, n)
    best, med = best_of(lambda: accel_time_0_100_s(mk, g, m))
    print(f"0-100 km/h time, {n} designs: median {med*1e3:.2f} ms -> {n/med:,.0f} designs/s")


if __name__ == "__main__":
    main()
