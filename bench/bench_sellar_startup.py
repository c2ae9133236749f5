"""Start to result over ROS: a loop against a feed-forward graph.

Times the whole command a user runs, ``bev-mdo optimize CONFIG --json --no-record --quiet``
over ROS (node processes started, discovery, the handshake, warm-up, the optimisation, the
result on stdout, every process stopped), for:

- ``leaf_nedc``: the default BEV problem, a feed-forward graph (data flow: one request per MDA);
- ``leaf_nedc_sized``: the same with ``problem.battery_sized_for_range: true`` (a loop through
  battery_sizing: Gauss-Seidel, hub and spoke);
- ``sellar_mdf``: examples/sellar/sellar_mdf.yaml (a loop y1 <-> y2; user disciplines).

Once, a loop stalled ~40 s at start (two data-flow warm-ups no node of a loop can
answer, each waiting timeout x (retries + 1)); now a loop is probed hub and spoke only.
Runs are interleaved round by round (the host is noisy); median, min and max per config.
The in-process run of each config is timed the same way, for reference. Asserts nothing.

    .venv/bin/python bench/bench_sellar_startup.py [--repeat 5] [--domain-id 22]
    (take /tmp/bev_ros.lock around it on a shared host)
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]


def configs(tmp: Path) -> dict[str, Path]:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["problem"]["battery_sized_for_range"] = True
    raw["name"] = "leaf_nedc_sized"
    sized = tmp / "leaf_nedc_sized.yaml"
    sized.write_text(yaml.safe_dump(raw, sort_keys=False))
    return {"leaf_nedc": REPO / "config" / "leaf_nedc.yaml", "leaf_nedc_sized": sized,
            "sellar_mdf": REPO / "examples" / "sellar" / "sellar_mdf.yaml"}


def run_once(path: Path, transport: str, domain: int, cwd: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    argv = [sys.executable, "-m", "bev_mdo", "optimize", str(path), "--json", "--quiet", "--no-record",
            "--transport", transport, "--domain-id", str(domain)]
    t0 = time.perf_counter()
    p = subprocess.run(argv, env=env, cwd=cwd, capture_output=True, text=True, timeout=600)
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 1):
        raise SystemExit(f"{path.name} ({transport}) failed with {p.returncode}: {p.stderr.strip()[-500:]}")
    doc = json.loads(p.stdout)
    warnings = [ln for ln in p.stderr.splitlines() if "retry" in ln or "WARN" in ln]
    return {"wall_s": wall, "optimisation_s": doc["wall_time_s"], "objective": doc["objective"],
            "iterations": doc["iterations"], "feasible": doc["feasible"],
            "retried": doc.get("retried_requests", 0), "warnings": warnings}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--domain-id", type=int, default=22)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "bench_sellar_startup.json"))
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        cfgs = configs(tmp)
        runs: dict[tuple[str, str], list[dict]] = {}
        for _ in range(args.repeat):
            for name, path in cfgs.items():
                for transport in ("ros", "inprocess"):
                    runs.setdefault((name, transport), []).append(run_once(path, transport, args.domain_id, tmp))
    rows = []
    for (name, transport), rs in runs.items():
        walls = [r["wall_s"] for r in rs]
        rows.append({"config": name, "transport": transport, "times_s": walls,
                     "median_s": statistics.median(walls), "min_s": min(walls), "max_s": max(walls),
                     "optimisation_median_s": statistics.median(r["optimisation_s"] for r in rs),
                     "objective": rs[-1]["objective"], "iterations": rs[-1]["iterations"],
                     "feasible": rs[-1]["feasible"], "retried_total": sum(r["retried"] for r in rs),
                     "retry_warnings_total": sum(len(r["warnings"]) for r in rs)})
    out = {"bench": "bench_sellar_startup", "repeat": args.repeat, "host_cpus": os.cpu_count(), "rows": rows}
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"start to result of `bev-mdo optimize CONFIG --json --no-record`, {args.repeat} runs each (interleaved)")
    print(f"{'config':16s} {'transport':10s} {'median s':>9s} {'min':>7s} {'max':>7s} {'opt. s':>8s} "
          f"{'retries':>7s} {'objective':>12s}")
    for r in rows:
        print(f"{r['config']:16s} {r['transport']:10s} {r['median_s']:9.2f} {r['min_s']:7.2f} {r['max_s']:7.2f} "
              f"{r['optimisation_median_s']:8.3f} {r['retried_total']:7d} {r['objective']:12.6f}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
