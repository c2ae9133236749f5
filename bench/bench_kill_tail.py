"""The end of a run after a SIGKILL of a reader and of the recorder, beside an undisturbed run (issue 19).

    . scripts/env.sh && flock /tmp/bev_ros.lock python bench/bench_kill_tail.py [--rounds 3]

`bev-mdo optimize config/leaf_nedc.yaml` (recorded, ros.timeout_s 1) on domain 67, alternately
undisturbed and with vehicle_mass and the recorder SIGKILLed once the first iteration is printed.
Figure: ``tail_s`` from the run's JSON summary, the time from the optimiser's return to the end
of the command's ROS part (final acknowledgements, the Leaf baseline evaluation, shutdown).
Reported: median and range per mode over the rounds, and the difference of the medians.
Writes bench/results/kill_tail.json.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
DOMAIN = 67




def run_once(config: Path, cwd: Path, bag: Path, kill: bool) -> dict:
    from bev_mdo.testing import child_processes, ros_env

    p = subprocess.Popen([sys.executable, "-m", "bev_mdo", "optimize", str(config), "--domain-id", str(DOMAIN),
                          "--bag", str(bag), "--json"], cwd=cwd, env=ros_env(DOMAIN), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    killed = 0
    for line in p.stderr:
        if kill and not killed and line.startswith("iter"):
            for pid, cmd in child_processes(p.pid).items():
                if "vehicle_mass_node" in cmd or "recorder_node" in cmd:
                    os.kill(pid, signal.SIGKILL)  # a child of the run this script started, by id
                    killed += 1
    out = json.loads(p.stdout.read())
    p.wait(timeout=60)
    return {"rc": p.returncode, "tail_s": out["tail_s"], "killed": killed, "restarts": out["node_restarts"]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "kill_tail.json"))
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_kill_"))
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"timeout_s": 1.0, "retries": 5, "discovery_wait_s": 60.0}
    config = tmp / "leaf.yaml"
    config.write_text(yaml.safe_dump(raw, sort_keys=False))
    runs = {"undisturbed": [], "killed": []}
    for r in range(args.rounds):
        for mode in runs:
            res = run_once(config, tmp, tmp / f"{mode}_{r}", kill=mode == "killed")
            assert res["rc"] == (3 if mode == "killed" else 0), res
            assert mode != "killed" or res["killed"] == 2, res
            runs[mode].append(res["tail_s"])
            time.sleep(1.0)
    figures = {m: {"median_s": statistics.median(v), "min_s": min(v), "max_s": max(v), "runs": v}
               for m, v in runs.items()}
    figures["killed_minus_undisturbed_median_s"] = (figures["killed"]["median_s"]
                                                    - figures["undisturbed"]["median_s"])
    figures["host_cpus"] = os.cpu_count()
    print(json.dumps(figures, indent=2))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
