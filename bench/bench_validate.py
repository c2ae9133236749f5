"""Speed of ``bev-mdo validate``: the whole training fleet on UDDS and HWFET, one batch per
cycle. Every figure is the median and range over ``--runs`` runs; the process figures of this tree and
of ``--baseline-rev`` (e.g. main, extracted with ``git archive``) alternate run by run, so both see the
same host load.

* ``python -c pass`` and ``python -c "import numpy"``: the floor of any Python process using numpy on
  this host (interpreter start with the venv's site hooks, then numpy's own import).
* ``validate process``: the whole ``python -m bev_mdo validate --json`` process, start-up included.
* ``validate after numpy``: in a fresh process that has already imported numpy, the time of
  ``from bev_mdo.cli import main; main(["validate", "--json"])``: everything bev_mdo adds (its imports,
  yaml, reading the fleet, the cycles and the parameter set, the model, the JSON), output to a buffer.
* ``compute``: predictions and statistics (bev_mdo.cli.validate.evaluate) per energy model, everything
  already loaded in the process (what a second call costs).
* the accuracy table (``tables`` in the JSON; rendered into docs/performance.md and
  docs/validation.md): per model, held-out-style MAPE and within-family pair metrics on UDDS and
  HWFET, on the same rows for every column (:func:`accuracy_table`). Deterministic: computed once.

Writes bench/results/bench_validate.json (schema of bench/_results.py).

    python bench/bench_validate.py [--runs 11] [--baseline-rev main] [--models chain quasi_static ...]
"""
from __future__ import annotations

import argparse
import json
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

import _results  # noqa: E402

from bev_mdo.cli.validate import evaluate  # noqa: E402
from bev_mdo.models import baselines  # noqa: E402
from bev_mdo.models import calibrate  # noqa: E402
from bev_mdo.models import fleet  # noqa: E402

# how each column's predictions are held out from the rows they are scored on
HELD_OUT = {
    "chain": "epa2022_chain refitted per fold, 5-fold by family (calibrate.cross_validate)",
    "flat": "thesis defaults, nothing fitted to the fleet",
    "breakdown": "thesis defaults, nothing fitted to the fleet",
    "quasi_static": "epa2022_quasi_static (loss model) refitted per fold, 5-fold by family",
    "topology_sm_sa": "the quasi_static model (SM-SA): the same held-out predictions",
    "quasi_static_thesis": "thesis parameter set, nothing fitted to the fleet",
    "baseline3": "a + b mass + c road-load work per cycle, fitted on the other folds (same split)",
    "fastsim": "FASTSim 2.1.5 defaults, nothing fitted (shipped fastsim_2.1.5.csv)",
}

AFTER_NUMPY = """
import contextlib, io, json, time
import numpy
t0 = time.perf_counter()
from bev_mdo.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    code = main(["validate", "--json"])
print(json.dumps({"ms": (time.perf_counter() - t0) * 1e3, "code": code}))
"""


def _process_ms(argv, pythonpath: Path) -> float:
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    t0 = time.perf_counter()
    subprocess.run([sys.executable, *argv], env=env, check=True, stdout=subprocess.DEVNULL, cwd=tempfile.gettempdir())
    return (time.perf_counter() - t0) * 1e3


def _after_numpy_ms(pythonpath: Path) -> float:
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    p = subprocess.run([sys.executable, "-c", AFTER_NUMPY], env=env, check=True, capture_output=True, text=True,
                       cwd=tempfile.gettempdir())
    out = json.loads(p.stdout.strip().splitlines()[-1])
    assert out["code"] == 0, p.stderr
    return out["ms"]


def _extract(rev: str) -> Path:
    """The bev_mdo package of git revision ``rev``, in a temporary folder (for a side-by-side baseline)."""
    d = Path(tempfile.mkdtemp(prefix="bench_validate_"))
    archive = subprocess.run(["git", "archive", rev, "bev_mdo"], cwd=ROOT, check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(d)], input=archive, check=True)
    return d


def accuracy_table(models=tuple(fleet.ENERGY_MODELS)) -> dict:
    """Held-out MAPE and pair metrics per model and cycle, every column on the same rows: the
    non-outlier vehicles that follow both cycles in every model (models/baselines.py)."""
    f = fleet.read_fleet()
    cycles = fleet.resampled_cycles()
    use = calibrate.usable(f, cycles)
    columns, scored = {}, {}
    for m in models:
        if m in ("chain", "quasi_static"):  # the models with a fitted parameter set: refitted per fold
            cv = calibrate.cross_validate(f, cycles=cycles, use=use, model=m)
            columns[m] = {c: f.measured[c] * (1.0 + cv["errors_pct"][c] / 100.0) for c in fleet.CYCLES}
        elif m == "topology_sm_sa":
            continue  # the same model as quasi_static: added below from its held-out column
        else:
            pred = fleet.predict(f, m, {}, cycles)
            columns[m] = {c: pred[c]["energy_wh_per_km"] for c in fleet.CYCLES}
            scored[m] = {c: pred[c]["follows"] for c in fleet.CYCLES}
    if "quasi_static" in columns:
        columns["topology_sm_sa"] = columns["quasi_static"]
        pred = fleet.predict(f, "quasi_static", {}, cycles)  # the model's defaults: the thesis' constants
        columns["quasi_static_thesis"] = {c: pred[c]["energy_wh_per_km"] for c in fleet.CYCLES}
        scored["quasi_static_thesis"] = {c: pred[c]["follows"] for c in fleet.CYCLES}
    columns = {m: columns[m] for m in [*models, "quasi_static_thesis"] if m in columns}  # the models' order
    columns["baseline3"] = baselines.three_constant_cv(f, use, cycles)
    columns["fastsim"] = baselines.read_fastsim(f)
    for name in columns:
        scored[name] = {c: scored.get(name, {}).get(c, np.ones(len(f), bool)) & use for c in fleet.CYCLES}
    t = baselines.reference_table(f, columns, scored)
    head = ["model", "held out how", "UDDS+HWFET MAPE %"]
    for c in ("udds", "hwfet"):
        head += [f"{c.upper()} MAPE %", f"{c.upper()} pair slope", f"{c.upper()} pair mean abs diff (points)"]
    rows = []
    for name in columns:
        n = t["udds"]["rows"] + t["hwfet"]["rows"]
        row = [name, HELD_OUT[name], _num((t["udds"][name]["mape_pct"] * t["udds"]["rows"] +
                                           t["hwfet"][name]["mape_pct"] * t["hwfet"]["rows"]) / n)]
        for c in ("udds", "hwfet"):
            cell = t[c][name]
            row += [_num(cell["mape_pct"]), _num(cell["pair_slope"]), _num(cell["pair_mad_points"])]
        rows.append(row)
    title = (f"Held-out accuracy on {f.path.rsplit('/', 1)[-1]}, 5-fold CV by model family (a platform sibling can "
             "sit in the fit; by make and with the two-speed platform held out: docs/validation.md, Limits): same "
             f"{t['udds']['rows']} rows (UDDS) / "
             f"{t['hwfet']['rows']} (HWFET), {t['udds']['pairs']} / {t['hwfet']['pairs']} within-family pairs; "
             "pair targets: slope 0.85-1.15, mean abs diff <= 2.5 points")
    return {"title": title, "columns": head, "rows": rows, "by_cycle": t}


def _num(x):
    return None if x is None or not np.isfinite(x) else round(float(x), 2)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=11)
    ap.add_argument("--baseline-rev", default=None, help="also measure the processes of this git revision")
    ap.add_argument("--models", nargs="+", default=["chain", "quasi_static"], help="models whose compute is timed")
    args = ap.parse_args(argv)
    load_start = os.getloadavg()[0]
    trees = {"this tree": ROOT}
    if args.baseline_rev:
        trees[f"{args.baseline_rev} (before)"] = _extract(args.baseline_rev)
    proc: dict = {k: [] for k in ("pass", "numpy")}
    for name in trees:
        proc[("process", name)] = []
        proc[("after_numpy", name)] = []
    for _ in range(args.runs):  # alternate everything run by run: the same load for all
        proc["pass"].append(_process_ms(["-c", "pass"], ROOT))
        proc["numpy"].append(_process_ms(["-c", "import numpy"], ROOT))
        for name, path in trees.items():
            proc[("process", name)].append(_process_ms(["-m", "bev_mdo", "validate", "--json"], path))
            proc[("after_numpy", name)].append(_after_numpy_ms(path))
    figures = [
        _results.figure("`python -c pass` (interpreter start, the venv's site hooks)", "ms", proc["pass"]),
        _results.figure("`python -c \"import numpy\"` (the floor of any numpy process)", "ms", proc["numpy"]),
    ]
    for name in trees:
        figures.append(_results.figure(f"`bev-mdo validate --json` whole process, {name}", "ms",
                                       proc[("process", name)], "< 100"))
    for name in trees:
        figures.append(_results.figure(f"validate after numpy (bev_mdo imports, files, model, JSON), {name}", "ms",
                                       proc[("after_numpy", name)], "< 100"))
    errors = {}
    for model in args.models:
        runs = args.runs if model in ("chain", "flat", "breakdown") else max(3, args.runs // 3)
        rep = evaluate(None, model)  # warm
        ts = []
        for _ in range(runs):
            t0 = time.perf_counter()
            rep = evaluate(None, model)
            ts.append((time.perf_counter() - t0) * 1e3)
        errors[model] = rep["stats"]["udds_hwfet"]["mean_abs_pct"]
        figures.append(_results.figure(f"compute, {model} model (62 vehicles x 2 cycles, in process, warm)", "ms", ts,
                                       "< 100" if model == "chain" else None,
                                       note=f"mean abs error {errors[model]:.2f} %"))
    table = accuracy_table()
    print(table["title"])
    for row in table["rows"]:
        print(" | ".join("-" if v is None else str(v) for v in row))
    for f in figures:
        print(f"{f['what']:95s} median {f['median']:7.1f} {f['unit']} [{f['min']:.1f}, {f['max']:.1f}]", flush=True)
    _results.write("bench_validate", figures,
                   extra={"vehicles": len(fleet.read_fleet()), "cycles": list(fleet.CYCLES),
                          "numpy": np.__version__, "load_average_1min_start": round(load_start, 2),
                          "mean_abs_pct": errors, "baseline_rev": args.baseline_rev,
                          "tables": [{k: table[k] for k in ("title", "columns", "rows")}],
                          "held_out": table["by_cycle"]})


if __name__ == "__main__":
    main()
