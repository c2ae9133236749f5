"""Benchmarks of signing and faults: signing overhead, cross-namespace latency, recovery after a kill.

    . scripts/env.sh && python bench/bench_faults.py [--n 2000] [--json]

1. Signing: HMAC-SHA256 sign + verify of a request and its result (CPU only), and the
   end-to-end evaluation latency against one discipline node with and without a key.
2. Latency: one evaluation (vehicle_mass, batch 1) round trip, with the coordinator
   on the same host and in another network namespace (veth, static peers). The
   namespace part is skipped with the reason where `ip netns` is not permitted.
3. Recovery: SIGKILL the node, then time until the next evaluation is answered
   (supervisor restart + process start + discovery + the coordinator's retry).
Network hygiene: localhost discovery and domains 87/88; the namespaces exist only
inside this run (10.200.2.1/24, 10.200.2.2/24) and are deleted at the end.
"""
from __future__ import annotations

import argparse
import json
import os
import secrets
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

DOMAIN_LOCAL, DOMAIN_NETNS = 87, 88
ADDR_NODE, ADDR_COORD = "10.200.2.1", "10.200.2.2"


def _config(tmp: Path, key: Path | None, **ros) -> str:
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"discovery_wait_s": 60.0, **ros}
    if key is not None:
        raw["ros"]["sign_key_file"] = str(key)
    p = tmp / f"bench_{len(list(tmp.iterdir()))}.yaml"
    p.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(p)


def _pct(xs: list[float]) -> dict:
    xs = sorted(xs)
    return {"median_us": 1e6 * statistics.median(xs), "p99_us": 1e6 * xs[int(0.99 * (len(xs) - 1))], "n": len(xs)}


# -- 1. signing, CPU only -----------------------------------------------------------------
def bench_sign(n: int) -> dict:
    from bev_mdo import protocol
    from bev_mdo.protocol.signing import Signer
    from bev_mdo.ros.common import stamp
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult

    out = {}
    for batch in (1, 7, 1000):
        s = Signer(secrets.token_bytes(32))
        req, res = EvaluationRequest(), EvaluationResult()
        req.run_id, req.discipline = "bench", "energy"
        protocol.to_named_array({"vehicle_mass_kg": np.full(batch, 1500.0), "gear_ratio": np.full(batch, 8.0)}, req.inputs)
        res.run_id, res.discipline, res.point_ok = "bench", "energy", [True] * batch
        protocol.to_named_array({"energy_wh_per_km": np.full(batch, 120.0)}, res.outputs)
        times = []
        for i in range(n):
            req.evaluation_id = res.evaluation_id = i + 1
            t0 = time.perf_counter()
            stamp(req.header)
            s.sign_request(req)
            assert s.verify_request(req) is None
            stamp(res.header)
            s.sign_result(res)
            assert s.verify_result(res) is None
            times.append(time.perf_counter() - t0)
        out[f"batch_{batch}"] = _pct(times)
    return out


# -- evaluation round trips (this process or a worker in a namespace) ----------------------
def latency_worker(config_path: str, n: int) -> dict:
    """Evaluate vehicle_mass `n` times, one point each; the per-evaluation wall time."""
    import rclpy

    from bev_mdo.config import load_config
    from bev_mdo.ros.coordinator_node import CoordinatorNode

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = CoordinatorNode(load_config(config_path), "bench-latency", context=ctx, node_name="bench_coordinator")
    ev = node.evaluator
    try:
        ev.wait_for_disciplines(["vehicle_mass"], 60.0)
        times = []
        for i in range(n + 50):
            batch = {"motor_kw": np.array([60.0 + i % 40]), "battery_kwh": np.array([24.0])}
            t0 = time.perf_counter()
            (r,) = ev.evaluate([("vehicle_mass", batch)])
            dt = time.perf_counter() - t0
            assert r.ok.all(), r.error
            if i >= 50:  # warm-up excluded
                times.append(dt)
        return {**_pct(times), "retried": ev.retried, "dropped": dict(ev.dropped)}
    finally:
        ev.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)


def _launcher(env: dict, config: str, prefix: list[str] = (), logs: Path | None = None):
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv

    la = Launcher(env, log_dir=logs)
    la.add("vehicle_mass", [*prefix, *discipline_argv("vehicle_mass", config)])
    la.supervise(interval_s=0.01)
    return la


def _env(domain: int, peer: str | None = None) -> dict:
    from bev_mdo.ros_settings import ros_environment, validate_ros

    ros = {"domain_id": domain}
    if peer:
        ros.update(discovery="static_peers", static_peers=[peer])
    env = ros_environment(validate_ros(ros))
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def bench_local(tmp: Path, n: int, key: Path) -> dict:
    """Same-host latency without and with signing, and recovery after SIGKILL."""
    out = {}
    os.environ.update({k: v for k, v in _env(DOMAIN_LOCAL).items() if k.startswith("ROS_")})
    for label, k in (("same_host", None), ("same_host_signed", key)):
        cfg = _config(tmp, k, timeout_s=2.0, retries=3)
        la = _launcher(_env(DOMAIN_LOCAL), cfg, logs=tmp / "logs")
        try:
            out[label] = latency_worker(cfg, n)
        finally:
            la.stop()
    out["recovery"] = bench_recovery(tmp)
    return out


def bench_recovery(tmp: Path, kills: int = 5, timeout_s: float = 0.1) -> dict:
    import rclpy

    from bev_mdo.config import load_config
    from bev_mdo.ros.coordinator_node import CoordinatorNode

    cfg = _config(tmp, None, timeout_s=timeout_s, retries=100)
    la = _launcher(_env(DOMAIN_LOCAL), cfg, logs=tmp / "logs_recovery")
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    node = CoordinatorNode(load_config(cfg), "bench-recovery", context=ctx, node_name="bench_recovery")
    ev = node.evaluator
    batch = {"motor_kw": np.array([80.0]), "battery_kwh": np.array([24.0])}
    try:
        ev.wait_for_disciplines(["vehicle_mass"], 60.0)
        for _ in range(20):
            ev.evaluate([("vehicle_mass", batch)])
        total, restart = [], []
        for _ in range(kills):
            t_kill = time.monotonic()
            la.kill("vehicle_mass")
            (r,) = ev.evaluate([("vehicle_mass", batch)])
            total.append(time.monotonic() - t_kill)
            restart.append(la.node("vehicle_mass").restart_times[-1] - t_kill)
            assert r.ok.all(), r.error
        return {"timeout_s": timeout_s, "kills": kills, "recovery_s_median": statistics.median(total),
                "recovery_s_max": max(total), "restart_spawned_after_s_median": statistics.median(restart),
                "retries": ev.retried}
    finally:
        ev.close()
        node.destroy_node()
        rclpy.shutdown(context=ctx)
        la.stop()


def bench_netns(tmp: Path, n: int) -> dict:
    """The node in one namespace, the evaluating coordinator in another."""
    sys.path.insert(0, str(REPO / "test" / "ros"))
    import test_netns as tn  # the namespace helper of the tests (same clean-up rules)

    why = tn.netns_unavailable()
    if why:
        return {"skipped": why}
    tn.ADDR_DISC, tn.ADDR_COORD = ADDR_NODE, ADDR_COORD  # this bench's own /24
    pair = tn.NetnsPair(f"b{os.getpid() % 10000}")
    try:
        pair.create()
        cfg = _config(tmp, None, timeout_s=2.0, retries=3)
        la = _launcher(_env(DOMAIN_NETNS, ADDR_COORD), cfg, ["ip", "netns", "exec", pair.a], tmp / "logs_netns")
        try:
            env = _env(DOMAIN_NETNS, ADDR_NODE)
            cp = subprocess.run(["ip", "netns", "exec", pair.b, sys.executable, __file__, "--worker", cfg,
                                 "--n", str(n)], env=env, capture_output=True, text=True, timeout=600)
            if cp.returncode != 0:
                return {"error": cp.stderr[-2000:]}
            return json.loads(cp.stdout.strip().splitlines()[-1])
        finally:
            la.stop()
    finally:
        pair.close()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="evaluations per latency measurement")
    ap.add_argument("--json", action="store_true", help="print the raw figures as JSON")
    ap.add_argument("--json-file", default=None, help="results file (default bench/results/faults.json)")
    ap.add_argument("--worker", metavar="CONFIG", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.worker:
        print(json.dumps(latency_worker(args.worker, args.n)))
        return 0
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        key = tmp / "bench.key"
        key.write_text(secrets.token_hex(32))
        key.chmod(0o600)  # a key file others may read is refused (protocol.signing.read_key)
        (tmp / "logs").mkdir()
        results = {"sign_verify_cpu": bench_sign(args.n), **bench_local(tmp, args.n, key),
                   "cross_namespace": bench_netns(tmp, args.n)}
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _results

    figs = [_results.figure(f"HMAC sign + verify of a request and its result (CPU), {k}", "µs", [v["median_us"]])
            for k, v in results["sign_verify_cpu"].items()]
    for k, what in (("same_host", "same host"), ("same_host_signed", "same host, signed"),
                    ("cross_namespace", "across network namespaces")):
        v = results.get(k, {})
        if "median_us" in v:
            figs.append(_results.figure(f"one evaluation round trip, {what}, median of {v['n']}", "µs", [v["median_us"]]))
            figs.append(_results.figure(f"one evaluation round trip, {what}, p99 of {v['n']}", "µs", [v["p99_us"]]))
    r = results["recovery"]
    if "recovery_s" in r:
        figs.append(_results.figure("recovery after SIGKILL (respawn + start-up + discovery + retry), per kill", "s",
                                    r["recovery_s"]))
    else:
        figs.append(_results.figure("recovery after SIGKILL, median over kills", "s", [r["recovery_s_median"]]))
    _results.write("faults", figs, path=args.json_file, extra={"raw": results})
    if args.json:
        print(json.dumps(results, indent=2))
        return 0
    print("signing (sign+verify of a request and its result, CPU):")
    for k, v in results["sign_verify_cpu"].items():
        print(f"  {k:12s} median {v['median_us']:7.1f} us  p99 {v['p99_us']:7.1f} us")
    print("one evaluation (vehicle_mass, batch 1), round trip:")
    for k in ("same_host", "same_host_signed", "cross_namespace"):
        v = results[k]
        if "median_us" in v:
            print(f"  {k:18s} median {v['median_us']:7.1f} us  p99 {v['p99_us']:7.1f} us  (n={v['n']})")
        else:
            print(f"  {k:18s} {v}")
    r = results["recovery"]
    print(f"recovery after SIGKILL (timeout {r['timeout_s']} s, {r['kills']} kills): median "
          f"{r['recovery_s_median']:.2f} s, max {r['recovery_s_max']:.2f} s; supervisor respawned after "
          f"{1e3 * r['restart_spawned_after_s_median']:.0f} ms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
