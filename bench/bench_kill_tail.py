"""The end of a run after a SIGKILL of a reader and of the recorder, beside an undisturbed run.

    . scripts/env.sh && flock /tmp/bev_bench.lock flock /tmp/bev_ros.lock python bench/bench_kill_tail.py \
        [--rounds 6] [--domain-id 67] [--keep]

`bev-mdo optimize config/leaf_nedc.yaml --compose none` (recorded, a process per discipline, ros.timeout_s 1,
retries 30) on one domain, in rounds of four
runs: undisturbed; ``killed``: vehicle_mass and the recorder SIGKILLed once the first iteration is
printed; ``killed_late``: both SIGKILLed once the LAST iteration (that of the round's undisturbed run)
is printed, so the kill lands at or after the optimiser's last evaluation, in the run's tail;
``reader_killed_late``: vehicle_mass alone, as late (the recorder lives and is waited for).
Figure: ``tail_s`` from the run's JSON summary, the time from the optimiser's return to the end
of the command's ROS part (final acknowledgements, shutdown; ``tail_parts_s`` splits it).
Reported: median and range per mode over the rounds, each killed mode's median and worst run
against the undisturbed median, and the 1-minute load average seen between runs.
Writes bench/results/kill_tail.json.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
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




def run_once(config: Path, cwd: Path, bag: Path, kill: bool, domain: int = DOMAIN, at_iteration: int = 0,
             victims: tuple[str, ...] = ("vehicle_mass_node", "recorder_node")) -> dict:
    """One recorded run; with `kill`, SIGKILL the `victims` once the progress line of iteration
    `at_iteration` (0: the first one printed) is read."""
    from bev_mdo.testing import child_processes, ros_env

    p = subprocess.Popen([sys.executable, "-m", "bev_mdo", "optimize", str(config), "--domain-id", str(domain),
                          "--compose", "none", "--bag", str(bag), "--json"], cwd=cwd, env=ros_env(domain), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    killed = 0
    err = []
    for line in p.stderr:
        err.append(line)
        if kill and not killed and line.startswith("iter") and int(line.split()[1]) >= at_iteration:
            for pid, cmd in child_processes(p.pid).items():
                if any(v in cmd for v in victims):
                    os.kill(pid, signal.SIGKILL)  # a child of the run this script started, by id
                    killed += 1
    out = json.loads(p.stdout.read())
    p.wait(timeout=60)
    return {"rc": p.returncode, "tail_s": out["tail_s"], "parts_s": out.get("tail_parts_s"), "killed": killed,
            "restarts": out["node_restarts"], "iterations": out["iterations"], "stderr": "".join(err)[-4000:]}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--domain-id", type=int, default=DOMAIN)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "kill_tail.json"))
    ap.add_argument("--keep", action="store_true", help="keep the bags and node logs (printed directory)")
    args = ap.parse_args()
    tmp = Path(tempfile.mkdtemp(prefix="bench_kill_"))
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"timeout_s": 1.0, "retries": 30, "discovery_wait_s": 60.0}  # 31 s for a restart under load
    config = tmp / "leaf.yaml"
    config.write_text(yaml.safe_dump(raw, sort_keys=False))
    runs = {"undisturbed": [], "killed": [], "killed_late": [], "reader_killed_late": []}
    parts = {m: [] for m in runs}
    load = [os.getloadavg()[0]]
    last = 0  # the last iteration of an undisturbed run: a kill there lands after the optimiser's last evaluation
    for r in range(args.rounds):
        for mode in runs:
            victims = ("vehicle_mass_node",) if mode == "reader_killed_late" else ("vehicle_mass_node", "recorder_node")
            res = run_once(config, tmp, tmp / f"{mode}_{r}", kill=mode != "undisturbed", domain=args.domain_id,
                           at_iteration=last if mode.endswith("late") else 0, victims=victims)
            if mode == "undisturbed":
                last = res["iterations"]
            assert res["rc"] == (3 if "recorder_node" in victims and mode != "undisturbed" else 0), res
            assert mode == "undisturbed" or res["killed"] == len(victims), res
            runs[mode].append(res["tail_s"])
            parts[mode].append(res["parts_s"])
            print(f"round {r} {mode}: tail {res['tail_s']:.3f} s {res['parts_s']}", file=sys.stderr, flush=True)
            load.append(os.getloadavg()[0])
            time.sleep(1.0)
    figures = {m: {"median_s": statistics.median(v), "min_s": min(v), "max_s": max(v), "runs": v,
                   "parts_s": parts[m]} for m, v in runs.items()}
    base = figures["undisturbed"]["median_s"]
    for m in ("killed", "killed_late", "reader_killed_late"):  # each killed run against the undisturbed median
        figures[f"{m}_minus_undisturbed_median_s"] = round(figures[m]["median_s"] - base, 3)
        figures[f"{m}_minus_undisturbed_max_s"] = round(figures[m]["max_s"] - base, 3)
    figures["load_average_1min"] = {"min": min(load), "max": max(load)}
    figures["host_cpus"] = os.cpu_count()
    if not args.keep:
        shutil.rmtree(tmp, ignore_errors=True)
    else:
        print(f"bags and logs kept in {tmp}", file=sys.stderr)
    print(json.dumps(figures, indent=2))
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
