"""Worker pools and composed processes (issue 18 benchmarks).

  . scripts/env.sh && flock /tmp/bev_ros.lock python bench/bench_pool.py [--reps 3] [--part scaling|compose|all]

1. scaling: a test discipline whose cost is a fixed wait per design (time.sleep, no CPU:
   test/ros/pool_discipline.py), batches of 64, 256 and 1024 designs shared by 1, 2, 4 and 8
   instances (one process each). Per (instances, batch): wall time of one batch (median and range
   of --reps runs), speed-up over one instance, efficiency = speed-up / instances, and the
   overhead per batch = wall time - (batch x wait / instances), i.e. what the pool costs beyond
   the ideal split (transport, split and join, the slowest share).
2. compose: one full MDA of one design over ROS (the data-flow path), p50/p99, with every
   discipline in its own process, with all six composed into ONE process, and in process;
   the three layouts measured in one run, alternating, --reps rounds of --n MDAs each.
Writes bench/results/bench_pool.json.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "test" / "ros"))
DOMAIN = 73
BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
RESULTS = REPO / "bench" / "results" / "bench_pool.json"


def _config(tmp: Path, wait_s: float) -> Path:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = BUILTINS + [{"name": "wait", "class": "pool_discipline:WaitPerDesign",
                                      "options": {"wait_s_per_design": wait_s}}]
    raw["ros"] = {"timeout_s": 30.0, "retries": 1, "discovery_wait_s": 120.0, "signing": False}
    path = tmp / "bench_pool.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _stats(values):
    v = np.asarray(values, dtype=float)
    return {"median": float(np.median(v)), "min": float(v.min()), "max": float(v.max()), "runs": [float(x) for x in v]}


def scaling(ctx, env, tmp: Path, reps: int, wait_s: float, counts, batches) -> dict:
    import rclpy

    from bev_mdo.config import load_config
    from bev_mdo.ros.evaluator import RosEvaluator
    from bev_mdo.ros.launch import Launcher, discipline_argv

    path = _config(tmp, wait_s)
    config = load_config(path)
    rng = np.random.default_rng(0)
    out: dict = {"wait_s_per_design": wait_s, "rows": []}
    single: dict[int, float] = {}
    env = {**env, "PYTHONPATH": f"{REPO / 'test' / 'ros'}:{env['PYTHONPATH']}"}
    for k in counts:
        launcher = Launcher(env)
        node = rclpy.create_node(f"bench_pool_{k}", context=ctx)
        ev = RosEvaluator(node, config=config, timeout_s=30.0, retries=1)
        try:
            for j in range(k):
                launcher.add(f"wait#{j}", discipline_argv("wait", str(path), instance=f"b{k}_{j}"))
            ev.wait_for_instances("wait", k, 120.0) if k > 1 else ev.wait_for_disciplines(["wait"], 120.0)
            for n in batches:
                batch = {"motor_kw": rng.uniform(40, 120, n), "gear_ratio": rng.uniform(1, 11, n)}
                ev.evaluate([("wait", batch)])  # throughput measured once before timing
                walls = []
                for _ in range(reps):
                    t0 = time.perf_counter()
                    res = ev.evaluate([("wait", batch)])[0]
                    walls.append(time.perf_counter() - t0)
                    assert res.ok.all(), res.error
                st = _stats(walls)
                ideal = n * wait_s / k
                if k == 1:
                    single[n] = st["median"]
                row = {"instances": k, "batch": n, "wall_s": st, "ideal_s": ideal,
                       "overhead_per_batch_ms": _stats([(w - ideal) * 1e3 for w in walls])}
                if n in single:
                    row["speed_up"] = single[n] / st["median"]
                    row["efficiency"] = row["speed_up"] / k
                out["rows"].append(row)
                print(f"instances {k}  batch {n:5d}  wall {st['median'] * 1e3:8.1f} ms "
                      f"[{st['min'] * 1e3:.1f}-{st['max'] * 1e3:.1f}]  ideal {ideal * 1e3:7.1f} ms"
                      + (f"  speed-up {row['speed_up']:.2f}  efficiency {row['efficiency']:.2f}"
                         if "speed_up" in row else ""), flush=True)
        finally:
            ev.close()
            node.destroy_node()
            launcher.stop()
    return out


def compose(ctx, env, reps: int, n: int) -> dict:
    import rclpy  # noqa: F401

    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
    from bev_mdo.ros.launch import Launcher, plan_processes

    cfg_path = str(REPO / "config" / "leaf_nedc.yaml")
    config = load_config(cfg_path)
    config = {**config, "ros": {**(config.get("ros") or {}), "signing": False}}
    names = discipline_names(config)
    layouts = {}
    setups = []
    for layout, spec in (("per_process", "none"), ("composed_one_process", "all")):
        launcher = Launcher(env)
        # each layout's nodes serve only their own coordinator's run (else both sets answer every MDA)
        run_id = f"benchpool{layout[:4]}{os.getpid()}"
        for label, argv in plan_processes(names, cfg_path, instance=layout[:4], compose=spec, run_id=run_id):
            launcher.add(label, argv)
        node = CoordinatorNode(config, run_id=run_id, context=ctx, node_name=f"bench_{layout}")
        setups.append((layout, launcher, node))
    try:
        forms = {}
        # the two layouts run one at a time: the other's processes are idle (blocked in a wait)
        for layout, launcher, node in setups:
            node.evaluator.wait_for_disciplines(names, 120.0)
            node.evaluator.warm_up(names)
            forms[layout] = (build_formulation(config, node.evaluator), launcher)
        forms["inprocess"] = (build_formulation(config, InProcessEvaluator(resolve_disciplines(config))), None)
        x = forms["inprocess"][0].x0[None, :]
        for form, _ in forms.values():
            for _ in range(50):
                form.analyse(x)
        p50 = {k: [] for k in forms}
        p99 = {k: [] for k in forms}
        for _ in range(reps):
            for layout, (form, _) in forms.items():
                lat = []
                for _ in range(n):
                    t0 = time.perf_counter()
                    form.analyse(x)
                    lat.append(time.perf_counter() - t0)
                p50[layout].append(float(np.percentile(lat, 50) * 1e6))
                p99[layout].append(float(np.percentile(lat, 99) * 1e6))
        for layout, (form, launcher) in forms.items():
            layouts[layout] = {"p50_us": _stats(p50[layout]), "p99_us": _stats(p99[layout]),
                               "processes": len(launcher.nodes) if launcher else 0}
            if launcher:
                ev = dict((lay, nd) for lay, _, nd in setups)[layout].evaluator
                layouts[layout]["data_flow_mdas"] = ev.flows
                layouts[layout]["dropped"] = dict(ev.dropped)
            print(f"{layout:22s} p50 {np.median(p50[layout]):7.0f} us [{min(p50[layout]):.0f}-{max(p50[layout]):.0f}]"
                  f"  p99 {np.median(p99[layout]):7.0f} us", flush=True)
    finally:
        for _, launcher, node in setups:
            node.evaluator.close()
            node.destroy_node()
            launcher.stop()
    return {"mdas_per_round": n, "rounds": reps, "layouts": layouts}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=["scaling", "compose", "all"], default="all")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--n", type=int, default=1000, help="MDAs per round (compose)")
    ap.add_argument("--wait-ms", type=float, default=1.0, help="wait per design of the test discipline")
    ap.add_argument("--instances", default="1,2,4,8")
    ap.add_argument("--batches", default="64,256,1024")
    args = ap.parse_args()
    os.environ["ROS_DOMAIN_ID"] = str(DOMAIN)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import tempfile

    import rclpy

    from bev_mdo.testing import ros_env

    env = ros_env(DOMAIN)
    figures = json.loads(RESULTS.read_text()) if RESULTS.exists() else {}
    figures["host"] = {"cpus": os.cpu_count(), "load_average_1min": os.getloadavg()[0],
                       "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime())}
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        with tempfile.TemporaryDirectory() as tmp:
            if args.part in ("scaling", "all"):
                figures["scaling"] = scaling(ctx, env, Path(tmp), args.reps, args.wait_ms * 1e-3,
                                             [int(k) for k in args.instances.split(",")],
                                             [int(b) for b in args.batches.split(",")])
            if args.part in ("compose", "all"):
                figures["compose"] = compose(ctx, env, args.reps, args.n)
    finally:
        rclpy.shutdown(context=ctx)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(figures, indent=2))
    print(f"wrote {RESULTS}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
