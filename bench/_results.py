"""Benchmark figures as JSON (``bench/results/<name>.json``), rendered into docs/performance.md by
``scripts/render_bench.py``. One schema for every bench:

    {"bench": "models", "command": "python bench/bench_models.py --runs 5", "date_utc": "...",
     "host": {"cpus": 2, "load_average_1min": 1.1, "python": "3.11.7"},
     "figures": [{"what": "...", "unit": "designs/s", "runs": [...], "median": m, "min": a, "max": b,
                  "target": ">= 100000"}, ...]}

``runs`` holds one value per repetition of the whole measurement (the host is noisy: the docs show
the median and the range, never a single run).
"""
from __future__ import annotations

import json
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"


def figure(what: str, unit: str, runs, target: str | None = None, note: str = "") -> dict:
    runs = [float(v) for v in runs]
    f = {"what": what, "unit": unit, "runs": runs, "median": float(np.median(runs)), "min": float(min(runs)),
         "max": float(max(runs))}
    if target:
        f["target"] = target
    if note:
        f["note"] = note
    return f


def write(name: str, figures: list[dict], command: str | None = None, path: str | Path | None = None,
          extra: dict | None = None) -> Path:
    """Write ``bench/results/<name>.json`` (or ``path``) and return its path."""
    out = Path(path) if path else RESULTS / f"{name}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    doc = {"bench": name,
           "command": command or "python " + " ".join([os.path.relpath(sys.argv[0], RESULTS.parents[1])] + sys.argv[1:]),
           "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
           "host": {"cpus": os.cpu_count(), "load_average_1min": round(os.getloadavg()[0], 2),
                    "python": platform.python_version()},
           "figures": figures, **(extra or {})}
    out.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    print(f"figures written to {out}")
    return out


def interleaved(methods, repeat: int) -> dict[str, list]:
    """Run each method's ``once()`` untimed once (imports, first discovery), then ``repeat`` rounds,
    every method once per round (side by side under the same host load); name -> the rounds' results."""
    runs = {m.name: [] for m in methods}
    for m in methods:
        m.once()
    for _ in range(repeat):
        for m in methods:
            runs[m.name].append(m.once())
    return runs
