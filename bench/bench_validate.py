"""Speed of ``bev-mdo validate`` (issue 16): the whole training fleet on UDDS and HWFET, one batch per
cycle, per energy model. Three figures per model, each the median and range over ``--runs`` runs:

* ``compute``: predictions + error statistics (bev_mdo.cli.validate.evaluate), cycles and
  parameter set already loaded in the process (what a second call in one process costs);
* ``cold_in_process``: the same with every cache cleared (reads the fleet CSV, the cycle CSVs,
  resamples, loads the parameter set);
* ``cli_process`` (chain only): the whole ``python -m bev_mdo validate --json`` process, start-up included.

Writes bench/results/bench_validate.json.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bev_mdo.cli.validate import evaluate  # noqa: E402
from bev_mdo.models import chain, cycles, fleet  # noqa: E402


def _clear():
    cycles._CACHE.clear()
    chain._STEPS.clear()


def _stats(ts):
    ts = np.asarray(ts) * 1e3
    return {"median_ms": float(np.median(ts)), "min_ms": float(ts.min()), "max_ms": float(ts.max()), "runs": len(ts)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--models", nargs="+", default=list(fleet.ENERGY_MODELS))
    args = ap.parse_args(argv)
    out = {"host": platform.node(), "python": platform.python_version(), "numpy": np.__version__,
           "vehicles": len(fleet.read_fleet()), "cycles": list(fleet.CYCLES), "models": {}}
    for model in args.models:
        runs = args.runs if model in ("chain", "flat", "breakdown") else max(3, args.runs // 5)
        evaluate(None, model)  # warm
        warm = []
        for _ in range(runs):
            t0 = time.perf_counter()
            rep = evaluate(None, model)
            warm.append(time.perf_counter() - t0)
        cold = []
        for _ in range(runs):
            _clear()
            t0 = time.perf_counter()
            evaluate(None, model)
            cold.append(time.perf_counter() - t0)
        out["models"][model] = {"compute": _stats(warm), "cold_in_process": _stats(cold),
                                "mean_abs_pct": rep["stats"]["udds_hwfet"]["mean_abs_pct"]}
        print(f"{model:15s} compute median {np.median(warm)*1e3:7.1f} ms [{min(warm)*1e3:.1f}, {max(warm)*1e3:.1f}]"
              f"  cold {np.median(cold)*1e3:7.1f} ms [{min(cold)*1e3:.1f}, {max(cold)*1e3:.1f}]  ({runs} runs)",
              flush=True)
    if "chain" in args.models:
        env = {**os.environ, "PYTHONPATH": str(ROOT)}
        proc = []
        for _ in range(max(3, args.runs // 3)):
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "bev_mdo", "validate", "--json"], env=env, check=True,
                           stdout=subprocess.DEVNULL)
            proc.append(time.perf_counter() - t0)
        out["models"]["chain"]["cli_process"] = _stats(proc)
        print(f"chain validate CLI process median {np.median(proc)*1e3:.0f} ms [{min(proc)*1e3:.0f}, {max(proc)*1e3:.0f}]")
    path = ROOT / "bench" / "results" / "bench_validate.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2))
    print("wrote", path)


if __name__ == "__main__":
    main()
