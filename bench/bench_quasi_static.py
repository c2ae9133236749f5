"""Benchmark: the quasi-static / topology models as the topology study calls them: energy on the
combined Artemis cycle (1 s grid, 5,215 steps) and NEDC range by repeated cycle (100 % -> 5 % SOC),
together, per topology, in batches of 100 and 1000; the compiled loops beside today's numpy loop
(``reference=True``), interleaved in one process. Also the first call of a fresh process, with the
compiled code cached on disk and cold (empty cache dir). Not a test.

    .venv/bin/python bench/bench_quasi_static.py [--runs 3] [--reference-runs 1] [--no-first-call]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from bev_mdo.models import topology as tp  # noqa: E402
from bev_mdo.models.cycles import load_cycle, resample  # noqa: E402

FIRST_CALL = """
import time; t0 = time.perf_counter()
from bev_mdo.models import topology as tp
from bev_mdo.models.cycles import load_cycle, resample
art, nedc = resample(load_cycle("artemis_combined"), 1.0), resample(load_cycle("nedc"), 1.0)
for t, args in [("SM-SA", (1590.0, 80.0, 24.0, 7.9)), ("DM-DA", (1640.0, 40.0, 24.0, 7.9, 40.0, 7.9)),
                ("IWM-SA", (1590.0, 40.0, 24.0, None)), ("IWM-DA", (1620.0, 20.0, 24.0, None, 20.0))]:
    tp.simulate(art, {}, t, *args); tp.range_by_repeated_cycle_km(nedc, {}, t, *args)
print(time.perf_counter() - t0)
"""


def designs(topology, n, rng):
    t = tp.get_topology(topology)
    kw = rng.uniform(40, 130, n) / (2 if t.front_motors == 2 else 1)
    kw_r = rng.uniform(20, 65, n) if t.two_axles else None
    ig = rng.uniform(4, 9.4, n) if t.geared else None
    ig_r = rng.uniform(4, 9.4, n) if t.geared and t.two_axles else None
    return (rng.uniform(1450, 1750, n), kw, rng.uniform(18, 30, n), ig, kw_r, ig_r)


def designs_per_s(topology, args, art, nedc, reference):
    """Designs per second of wall time and per CPU-second of this process (all its threads: on
    a loaded host the wall figure is the host's share, the CPU figure the code's own cost)."""
    t0, c0 = time.perf_counter(), time.process_time()
    tp.simulate(art, {}, topology, *args, reference=reference)
    tp.range_by_repeated_cycle_km(nedc, {}, topology, *args, reference=reference)
    return len(args[0]) / (time.perf_counter() - t0), len(args[0]) / (time.process_time() - c0)


def first_call_s(cache_dir: str | None) -> float:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if cache_dir:
        env["NUMBA_CACHE_DIR"] = cache_dir
    out = subprocess.run([sys.executable, "-c", FIRST_CALL], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    import _results

    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3, help="runs of the compiled loops per batch size")
    ap.add_argument("--reference-runs", type=int, default=1, help="runs of today's numpy loop per batch size")
    ap.add_argument("--no-first-call", action="store_true")
    ap.add_argument("--json", default=None, help="results file (default bench/results/quasi_static.json)")
    a = ap.parse_args()
    art, nedc = resample(load_cycle("artemis_combined"), 1.0), resample(load_cycle("nedc"), 1.0)
    rng = np.random.default_rng(0)
    figs = []
    for t in tp.TOPOLOGIES:
        designs_per_s(t, designs(t, 4, rng), art, nedc, False)  # load (or compile) the compiled code
        target = {1: {100: 1000, 1000: 2000}, 2: {100: 500, 1000: 1000}}[1 + tp.get_topology(t).two_axles]
        for n in (100, 1000):
            args = designs(t, n, rng)
            runs = {"compiled": [], "numpy loop": []}
            cpu = []
            for i in range(max(a.runs, a.reference_runs)):  # interleaved: both see the same host load
                if i < a.runs:
                    wall, per_cpu_s = designs_per_s(t, args, art, nedc, False)
                    runs["compiled"].append(wall)
                    cpu.append(per_cpu_s)
                if i < a.reference_runs:
                    runs["numpy loop"].append(designs_per_s(t, args, art, nedc, True)[0])
            if n == 1000:
                runs["compiled, per CPU-second of the process"] = cpu
            for how, r in runs.items():
                if not r:  # --reference-runs 0
                    continue
                f = _results.figure(f"{t} energy (Artemis) + NEDC range, batches of {n}, {how}",
                                    "designs/CPU-s" if "CPU" in how else "designs/s", r,
                                    target=f">= {target[n]}" if how == "compiled" else None)
                figs.append(f)
                print(f"{f['what']}: median {f['median']:,.0f} {f['unit']} (range {f['min']:,.0f}-{f['max']:,.0f}, "
                      f"{len(r)} runs)", flush=True)
    if not a.no_first_call:
        cached = [first_call_s(None) for _ in range(3)]
        with tempfile.TemporaryDirectory() as d:
            cold = [first_call_s(d)]
        for what, r in (("first call of a fresh process, 4 topologies, compiled code cached", cached),
                        ("first call of a fresh process, 4 topologies, cold compile (empty cache)", cold)):
            f = _results.figure(what, "s", r)
            figs.append(f)
            print(f"{what}: median {f['median']:.2f} s (range {f['min']:.2f}-{f['max']:.2f}, {len(r)} runs)")
    _results.write("quasi_static", figs, path=a.json)


if __name__ == "__main__":
    main()
