"""Worker pools and composed processes.

  . scripts/env.sh && flock /tmp/bev_ros.lock python bench/bench_pool.py [--reps 3] [--part scaling|compose|all]

1. scaling: a test discipline whose cost is a fixed wait per design (time.sleep, no CPU:
   test/ros/pool_discipline.py), batches of 64, 256 and 1024 designs shared by 1, 2, 4 and 8
   instances (one process each). Per (instances, batch): wall time of one batch (median and range
   of --reps runs), speed-up over one instance, efficiency = speed-up / instances, and the
   overhead per batch = wall time - (batch x wait / instances), i.e. what the pool costs beyond
   the ideal split (transport, split and join, the slowest share).
2. compose: one full MDA of one design over ROS (the data-flow path), p50/p99, with every
   discipline in its own process, with all six composed into ONE process, with all six composed
   into the coordinator's own process (--compose coordinator, composed.Beside), and in process;
   the four layouts measured in one run, alternating, --reps rounds of --n MDAs each; each ROS
   layout on a domain of its own (--domain + 1, + 2, + 3), so none sees another's traffic.
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
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv

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


def compose(ctx, env, reps: int, n: int, domain: int | None = None) -> dict:
    """With ``domain``, each layout runs on a domain of its own (``domain`` + 1, + 2) with a context
    of its own: on one shared domain every data-flow request and result of one layout is also
    delivered to the other layout's (idle) nodes and coordinator, which inflates both."""
    import rclpy

    from bev_mdo.testing import ros_env

    from bev_mdo.config import load_config, resolve_disciplines, run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import plan_processes

    cfg_path = str(REPO / "config" / "leaf_nedc.yaml")
    config = load_config(cfg_path)
    config = {**config, "ros": {**(config.get("ros") or {}), "signing": False}}
    names = discipline_names(config)
    layouts = {}
    setups = []
    contexts = []
    load0 = os.getloadavg()[0]
    for k, (layout, spec) in enumerate((("per_process", "none"), ("composed_one_process", "all"))):
        if domain is not None:
            lctx = rclpy.context.Context()
            rclpy.init(context=lctx, domain_id=domain + 1 + k)
            contexts.append(lctx)
            launcher = Launcher(ros_env(domain + 1 + k))
        else:
            lctx = ctx
            launcher = Launcher(env)
        # each layout's nodes serve only their own coordinator's run (else both sets answer every MDA)
        run_id = f"benchpool{layout[:4]}{os.getpid()}"
        for label, argv in plan_processes(names, cfg_path, instance=layout[:4], compose=spec, run_id=run_id):
            launcher.add(label, argv)
        node = CoordinatorNode(config, run_id=run_id, context=lctx, node_name=f"bench_{layout}")
        setups.append((layout, launcher, node))
    # --compose coordinator: the six nodes in THIS process, served by the coordinator's own loop
    from bev_mdo.ros.composed import Beside

    if domain is not None:
        lctx = rclpy.context.Context()
        rclpy.init(context=lctx, domain_id=domain + 3)
        contexts.append(lctx)
    else:
        lctx = ctx
    run_id = f"benchpoolbesi{os.getpid()}"
    beside = Beside(config, names, lctx, run_id=run_id)
    node = CoordinatorNode(config, run_id=run_id, context=lctx, node_name="bench_composed_beside_coordinator")
    beside.attach(node.evaluator)
    setups.append(("composed_beside_coordinator", Launcher(env), node))
    try:
        forms = {}
        # the two layouts run one at a time: the other's processes are idle (blocked in a wait)
        for layout, launcher, node in setups:
            node.evaluator.wait_for_disciplines(names, 120.0)
            node.evaluator.warm_up(names)
            forms[layout] = (build_formulation(run_settings(config), node.evaluator), launcher)
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
        beside.close()
        for _, launcher, node in setups:
            node.evaluator.close()
            node.destroy_node()
            launcher.stop()
        for lctx in contexts:
            rclpy.shutdown(context=lctx)
    return {"mdas_per_round": n, "rounds": reps, "layouts": layouts,
            "load_average_1min": {"before": load0, "after": os.getloadavg()[0]},
            "domains": "one per layout" if domain is not None else "shared"}


def _artemis(tmp: Path) -> Path:
    raw = yaml.safe_load((REPO / "config" / "topologies_artemis.yaml").read_text())
    raw["ros"] = {**(raw.get("ros") or {}), "signing": False, "discovery_wait_s": 120.0, "retries": 1}
    path = tmp / "bench_pool_artemis.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _designs(form, n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo = np.array([d.lower for d in form.problem.design_variables])
    hi = np.array([d.upper for d in form.problem.design_variables])
    return lo + (hi - lo) * rng.uniform(size=(n, lo.size))


def _set_energy_instances(launcher, ev, path: Path, k: int) -> None:
    """Make `k` (1 or 2) energy instances live: start or stop the second one and wait for the graph."""
    from bev_mdo.processes import discipline_argv

    has = any(n.label == "energy#1" for n in launcher.nodes)
    if k == 2 and not has:
        launcher.add("energy#1", discipline_argv("energy", str(path), instance="e1"))
        ev.wait_for_instances("energy", 2, 120.0)
    elif k == 1 and has:
        launcher.remove("energy#1")
        deadline = time.monotonic() + 60.0
        while len(ev._present_instances("energy")[0]) > 1 and time.monotonic() < deadline:
            ev._executor.spin_once(timeout_sec=0.05)
        assert len(ev._live("energy") or [1]) == 1


def energy(ctx, env, tmp: Path, reps: int, batches) -> dict:
    """The quasi-static energy model on Artemis (CPU-bound): one batch to the energy discipline,
    1 and 2 instances alternating per round (the second instance stopped and started between)."""
    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv

    path = _artemis(tmp)
    config = load_config(path)
    names = discipline_names(config)
    local = InProcessEvaluator(resolve_disciplines(config))
    form = build_formulation(config, local)
    batches_in = {}
    for n in batches:
        values = form.analyse(_designs(form, n, seed=n)).values
        batches_in[n] = {k: np.asarray(values[k]) for k in local.specs["energy"].inputs}
    launcher = Launcher(env)
    run_id = f"benchpoolenergy{os.getpid()}"
    launcher.add("energy", discipline_argv("energy", str(path), run_id=run_id))
    node = CoordinatorNode(config, run_id=run_id, context=ctx, node_name="bench_pool_energy")
    ev = node.evaluator
    walls: dict = {(k, n): [] for k in (1, 2) for n in batches}
    inproc: dict = {n: [] for n in batches}
    try:
        ev.wait_for_disciplines(["energy"], 120.0)
        for r in range(reps):
            for k in ((1, 2) if r % 2 == 0 else (2, 1)):
                _set_energy_instances(launcher, ev, path, k)
                for n in batches:
                    ev.evaluate([("energy", batches_in[n])])  # warm (and throughput measured)
                    t0 = time.perf_counter()
                    res = ev.evaluate([("energy", batches_in[n])])[0]
                    walls[(k, n)].append(time.perf_counter() - t0)
                    assert res.ok.any(), res.error
            for n in batches:
                t0 = time.perf_counter()
                local.evaluate([("energy", batches_in[n])])
                inproc[n].append(time.perf_counter() - t0)
        rows = []
        for n in batches:
            one, two = _stats(walls[(1, n)]), _stats(walls[(2, n)])
            ref = _stats(inproc[n])
            row = {"batch": n, "inprocess_s": ref, "one_instance_s": one, "two_instances_s": two,
                   "speed_up": one["median"] / two["median"],
                   "overhead_one_instance_ms": (one["median"] - ref["median"]) * 1e3,
                   "compute_per_design_ms": ref["median"] / n * 1e3}
            rows.append(row)
            print(f"energy batch {n:4d}: in process {ref['median'] * 1e3:7.1f} ms  1 instance "
                  f"{one['median'] * 1e3:7.1f} [{one['min'] * 1e3:.1f}-{one['max'] * 1e3:.1f}]  2 instances "
                  f"{two['median'] * 1e3:7.1f} [{two['min'] * 1e3:.1f}-{two['max'] * 1e3:.1f}]  "
                  f"speed-up {row['speed_up']:.2f}", flush=True)
        return {"config": "config/topologies_artemis.yaml (quasi-static, Artemis combined)", "rounds": reps,
                "rows": rows, "pools": ev.pool_summary(), "names": names}
    finally:
        ev.close()
        node.destroy_node()
        launcher.stop()


def _variant(token: str) -> tuple[int, bool, int]:
    """``--pareto-variants`` item: energy instances, then ``w`` (waves) and/or ``m<N>`` (ros.pool_min_rows
    N for energy): ``1``, ``2``, ``2w``, ``2m128``."""
    import re

    m = re.fullmatch(r"(\d+)(w?)(?:m(\d+))?", token.strip())
    if not m:
        raise SystemExit(f"--pareto-variants: bad item {token!r} (e.g. 1,2,2w,2m128)")
    return int(m.group(1)), bool(m.group(2)), int(m.group(3) or 1)


def pareto(ctx, env, tmp: Path, pop: int, generations: int, counts, waves: bool = False) -> dict:
    """NSGA-II (run_nsga2 over the MDF MDA, as ``bev-mdo pareto`` runs it) over ROS with 1 and 2
    energy instances (every other discipline one process), and in process. `counts` items are
    energy instance counts, or (instances, waves, pool_min_rows) variants (_variant)."""
    from bev_mdo.config import load_config, resolve_disciplines, run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.mdo.pareto import run_nsga2
    from bev_mdo.cli.pareto import OBJECTIVES
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv

    path = _artemis(tmp)
    config = load_config(path)
    names = discipline_names(config)
    out = {"pop": pop, "generations": generations, "runs": []}
    fronts = {}
    for item in counts:
        k, waves_k, min_rows = item if isinstance(item, tuple) else (item, waves, 1)
        label = f"{k}{'w' if waves_k else ''}{f'm{min_rows}' if min_rows > 1 else ''}"
        t_start = time.perf_counter()
        load_before = os.getloadavg()[0]
        if k == 0:
            ev, launcher, node = InProcessEvaluator(resolve_disciplines(config)), None, None
        else:
            launcher = Launcher(env)
            run_id = f"benchpoolpareto{k}{os.getpid()}"
            for name in names:
                launcher.add(name, discipline_argv(name, str(path), run_id=run_id))
            for j in range(1, k):
                launcher.add(f"energy#{j}", discipline_argv("energy", str(path), instance=f"p{j}", run_id=run_id))
            node = CoordinatorNode(config, run_id=run_id, context=ctx, node_name=f"bench_pool_pareto{k}")
            ev = node.evaluator
            ev.wait_for_disciplines(names, 120.0)
            if k > 1:
                ev.wait_for_instances("energy", k, 120.0)
            ev.warm_up(names)
            ev.pool_data_flow = not waves_k
            ev.pool_min_rows = {"energy": min_rows}
        try:
            t0 = time.perf_counter()
            res = run_nsga2(build_formulation(run_settings(config), ev, "mdf"), OBJECTIVES, pop_size=pop,
                            generations=generations, seed=1)
            wall = time.perf_counter() - t0
            fronts[label] = np.asarray(res.F) if hasattr(res, "F") else None
            entry = {"variant": label, "energy_instances": k, "wall_s": wall,
                     "pool_mda": "waves" if waves_k else "data_flow_shares", "pool_min_rows": min_rows,
                     "start_up_s": t0 - t_start, "load_average_1min_before": load_before,
                     "load_average_1min_after": os.getloadavg()[0]}
            if node is not None:
                entry["data_flow_mdas"] = ev.flows
                entry["flow_shares"] = ev.flow_shares
                entry["pools"] = ev.pool_summary()
                entry["retried"] = ev.retried
            out["runs"].append(entry)
            print(f"pareto {pop}x{generations}, energy instances {k or 'in process'} ({label}): {wall:.1f} s "
                  f"load {load_before:.1f}->{os.getloadavg()[0]:.1f}", flush=True)
        finally:
            if node is not None:
                ev.close()
                node.destroy_node()
                launcher.stop()
    ref = next(iter(fronts.values()))
    out["identical_fronts_to_first"] = sorted(k for k in fronts if np.array_equal(fronts[k], ref))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=["scaling", "compose", "energy", "pareto", "all"], default="all")
    ap.add_argument("--domain", type=int, default=DOMAIN, help="ROS domain id")
    ap.add_argument("--energy-batches", default="64,128,256,512")
    ap.add_argument("--pop", type=int, default=100)
    ap.add_argument("--generations", type=int, default=30)
    ap.add_argument("--pool-waves", action="store_true", help="pareto: MDAs with a pool in waves, not data flow")
    ap.add_argument("--pareto-instances", default="1,2", help="energy instances per run (0: in process)")
    ap.add_argument("--pareto-variants", default=None,
                    help="instead of --pareto-instances: runs like 1,2,2w,2m128 (w: waves, mN: pool_min_rows N)")
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--n", type=int, default=1000, help="MDAs per round (compose)")
    ap.add_argument("--wait-ms", type=float, default=1.0, help="wait per design of the test discipline")
    ap.add_argument("--instances", default="1,2,4,8")
    ap.add_argument("--batches", default="64,256,1024")
    ap.add_argument("--json", default=str(RESULTS), help="results file (updated: other parts are kept)")
    ap.add_argument("--shared-domain", action="store_true",
                    help="compose: both layouts on --domain (as before 2026-12-02; they disturb each other)")
    args = ap.parse_args()
    os.environ["ROS_DOMAIN_ID"] = str(args.domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import tempfile

    import rclpy

    from bev_mdo.testing import ros_env

    env = ros_env(args.domain)
    results = Path(args.json)
    figures = json.loads(results.read_text()) if results.exists() else {}
    figures.setdefault("hosts", {})[args.part + ("_waves" if args.pool_waves else "")] = figures["host"] = {"cpus": os.cpu_count(), "load_average_1min": os.getloadavg()[0],
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
                figures["compose"] = compose(ctx, env, args.reps, args.n,
                                             None if args.shared_domain else args.domain)
            if args.part in ("energy", "all"):
                figures["energy"] = energy(ctx, env, Path(tmp), args.reps,
                                           [int(b) for b in args.energy_batches.split(",")])
                figures["energy"]["load_average_1min_after"] = os.getloadavg()[0]
            if args.part in ("pareto", "all"):
                key = "pareto_waves" if args.pool_waves else "pareto"
                if args.pareto_variants:
                    key = "pareto_variants"
                    runs = [_variant(t) for t in args.pareto_variants.split(",")]
                else:
                    runs = [int(k) for k in args.pareto_instances.split(",")]
                figures[key] = pareto(ctx, env, Path(tmp), args.pop, args.generations, runs, args.pool_waves)
    finally:
        rclpy.shutdown(context=ctx)
    if args.part == "compose":  # rendered into docs/performance.md (scripts/render_bench.py)
        lay = figures["compose"]["layouts"]
        figures["bench"] = "bench_pool compose: one full MDA (leaf_nedc, one design) over ROS, four layouts in one run"
        figures["command"] = " ".join(["python bench/bench_pool.py", *sys.argv[1:]])
        figures["date_utc"] = figures["host"]["date_utc"]
        figures["host"] = {**figures["host"], "load_average_1min": round(os.getloadavg()[0], 2),
                           "python": sys.version.split()[0]}
        what = {"per_process": "MDA p50, a process per discipline",
                "composed_one_process": "MDA p50, all six composed into one process (--compose all)",
                "composed_beside_coordinator": "MDA p50, all six in the coordinator's process (--compose coordinator)",
                "inprocess": "MDA p50, in process (no ROS)"}
        figures["figures"] = [{"what": what[k], "unit": "us", **{x: lay[k]["p50_us"][x] for x in ("median", "min", "max", "runs")},
                               **({"target": "<= 1000"} if k == "composed_beside_coordinator" else {})}
                              for k in what if k in lay]
    results.parent.mkdir(parents=True, exist_ok=True)
    results.write_text(json.dumps(figures, indent=2))
    print(f"wrote {results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
