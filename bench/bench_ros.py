"""Latency and throughput of the ROS transport.

  . scripts/env.sh && python bench/bench_ros.py [--n 2000] [--json FILE]

Measures, on this host, every process localhost-only on its own domain:
  1. raw rclpy ping-pong: one EvaluationRequest out, one EvaluationResult back, over topics
     (typed messages, rclpy executor), and the same exchange the way bev_mdo's hot path does
     it (raw CDR bytes, one rcl wait set);
  2. floors: the same data-flow message pattern through six stand-in processes that only echo
     (the transport's share), echo and run their model, or decode + run the model + encode
     (the least a Python node can do), p50/p99 and their CPU;
  3. latency of one full multidisciplinary evaluation (one design point, one data-flow
     request, six discipline processes), p50 and p99, and the CPU time it costs in every
     process (the host has 2 cores: CPU per MDA, not hops, bounds the latency);
  4. batched throughput: design evaluations per second with large batches;
  5. the in-process MDA of the same point, for reference.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
DOMAIN = 61

ECHO = textwrap.dedent(
    """
    import rclpy
    from rclpy.node import Node
    from bev_mdo.ros.common import REQUEST_QOS, RESULT_QOS
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult
    rclpy.init()
    node = Node("bench_echo")
    pub = node.create_publisher(EvaluationResult, "/bench/pong", RESULT_QOS)
    def on(msg):
        out = EvaluationResult(); out.run_id = msg.run_id; out.evaluation_id = msg.evaluation_id
        out.outputs = msg.inputs
        pub.publish(out)
    node.create_subscription(EvaluationRequest, "/bench/ping", on, REQUEST_QOS)
    try:
        rclpy.spin(node)
    except BaseException:
        pass
    """
)


LEAN_ECHO = textwrap.dedent(
    """
    import rclpy
    from rclpy.node import Node
    from bev_mdo.ros.common import REQUEST_QOS, RESULT_QOS
    from bev_mdo.ros.fastwait import MultiWaiter
    from bev_mdo_msgs.msg import EvaluationRequest
    rclpy.init()
    node = Node("bench_lean_echo")
    pub = node.create_publisher(EvaluationRequest, "/bench/lean_pong", RESULT_QOS)
    sub = node.create_subscription(EvaluationRequest, "/bench/lean_ping", lambda m: None, REQUEST_QOS, raw=True)
    waiter, hot = MultiWaiter(node.context), [(sub, lambda data, _info: pub.publish(data))]
    try:
        while rclpy.ok():
            if waiter.take_all(hot) == 0:
                waiter.wait([sub], 1.0)
    except BaseException:
        pass
    """
)


def lean_ping_pong(ctx, env, n):
    """Round trips of raw CDR bytes through one rcl wait set on each side (bev_mdo's hot path)."""
    from rclpy.node import Node

    from bev_mdo import protocol
    from bev_mdo.ros.common import REQUEST_QOS, RESULT_QOS
    from bev_mdo.ros.fastwait import MultiWaiter
    from bev_mdo_msgs.msg import EvaluationRequest

    child = subprocess.Popen([sys.executable, "-c", LEAN_ECHO], env=env)
    node = Node("bench_lean_ping", context=ctx)
    pub = node.create_publisher(EvaluationRequest, "/bench/lean_ping", REQUEST_QOS)
    sub = node.create_subscription(EvaluationRequest, "/bench/lean_pong", lambda m: None, RESULT_QOS, raw=True)
    waiter, hot = MultiWaiter(ctx), [(sub, lambda data, _info: got.append(data))]
    got = []
    while pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1:
        time.sleep(0.02)
    req = protocol.request("bench", 0, "x")
    req.inputs = protocol.batch({"motor_kw": np.array([80.0]), "gear_ratio": np.array([8.0])})
    data = protocol.encode_request(req)
    lat = []
    for i in range(n + 50):
        t0 = time.perf_counter()
        pub.publish(data)
        while waiter.take_all(hot) == 0:
            waiter.wait([sub], 1.0)
        if i >= 50:
            lat.append(time.perf_counter() - t0)
    child.terminate()
    child.wait()
    node.destroy_node()
    return lat


# The data-flow graph of the default problem (a discipline -> the topics it waits for; "request"
# is the coordinator's), served by stand-in processes that do only part of a discipline node's work:
#   echo    - forward the last bytes received (no decode, no model): what the transport costs;
#   compute - the same, plus the discipline's own compute() on fixed one-point inputs;
#   codec   - decode every source's message (bev_mdo.protocol), compute() on the decoded columns, encode
#             the outputs with the forwarded columns, publish: the least any Python node can do.
# A real node does the codec step plus the protocol (ids, validation, failed points, counters).
DAG = {"vehicle_mass": ["request"], "energy": ["vehicle_mass"], "range": ["energy"],
       "acceleration": ["vehicle_mass"], "motor_speed": ["request"], "cost": ["request"]}
FLOOR_MODES = ("echo", "compute", "codec")

DAG_ECHO = textwrap.dedent(
    """
    import sys
    import numpy as np
    import rclpy
    from rclpy.node import Node
    from bev_mdo import protocol
    from bev_mdo.ros.common import MDA_RESULT_QOS
    from bev_mdo.ros.fastwait import MultiWaiter
    from bev_mdo_msgs.msg import EvaluationResult
    name, sources, mode, config = sys.argv[1], sys.argv[2].split(","), sys.argv[3], sys.argv[4]
    if mode != "echo":
        from bev_mdo.config import load_config, resolve_disciplines
        disc = {d.name: d for d in resolve_disciplines(load_config(config))}[name]
        fixed = {"motor_kw": 80.0, "gear_ratio": 7.94, "battery_kwh": 24.0, "vehicle_mass_kg": 1590.0,
                 "energy_wh_per_km": 96.5}
        fixed = {k: np.array([fixed[k]]) for k in disc.inputs}
    rclpy.init()
    node = Node("bench_dag_" + name)
    pub = node.create_publisher(EvaluationResult, "/bench/dag/" + name, MDA_RESULT_QOS)
    subs = [node.create_subscription(EvaluationResult, "/bench/dag/" + s, lambda m: None, MDA_RESULT_QOS, raw=True)
            for s in sources]
    got = [0]
    columns = {}
    def on(data, _info):  # answer once every source has answered
        if mode == "codec":
            msg = protocol.decode_result(data)
            columns.update(protocol.from_named_array(msg.outputs))
        got[0] += 1
        if got[0] < len(subs):
            return
        got[0] = 0
        if mode == "echo":
            return pub.publish(data)
        if mode == "compute":
            disc.compute({k: v.copy() for k, v in fixed.items()})
            return pub.publish(data)
        out = disc.compute({k: columns[k].copy() for k in disc.inputs})
        res = protocol.result()
        res.run_id, res.evaluation_id, res.discipline, res.flow = msg.run_id, msg.evaluation_id, name, msg.flow
        res.point_ok = np.ones(1, bool)
        res.outputs = protocol.batch({**columns, **out})
        pub.publish(protocol.encode_result(res))
    pairs = [(s, on) for s in subs]
    waiter = MultiWaiter(node.context)
    try:
        while rclpy.ok():
            if waiter.wait(subs, 1.0):
                waiter.take_ready(pairs)
    except BaseException:
        pass
    """
)


def mda_floor(ctx, env, n, mode="echo", config=""):
    """One MDA's message pattern through six stand-in processes doing `mode` (see DAG_ECHO):
    (latencies, CPU s per MDA per process)."""
    from rclpy.node import Node

    from bev_mdo import protocol
    from bev_mdo.ros.common import MDA_RESULT_QOS
    from bev_mdo.ros.fastwait import MultiWaiter
    from bev_mdo_msgs.msg import EvaluationResult

    children = [subprocess.Popen([sys.executable, "-c", DAG_ECHO, d, ",".join(src), mode, config], env=env)
                for d, src in DAG.items()]
    node = Node(f"bench_dag_coordinator_{mode}", context=ctx)
    pub = node.create_publisher(EvaluationResult, "/bench/dag/request", MDA_RESULT_QOS)
    subs = [node.create_subscription(EvaluationResult, "/bench/dag/" + d, lambda m: None, MDA_RESULT_QOS, raw=True)
            for d in DAG]
    roots = sum(src == ["request"] for src in DAG.values())
    while pub.get_subscription_count() < roots or any(s.get_publisher_count() < 1 for s in subs):
        if any(c.poll() is not None for c in children):
            raise RuntimeError(f"a {mode} stand-in process exited during discovery")
        time.sleep(0.02)
    # The request as one result-typed message (every topic of the pattern has one type): the design
    # variables of one point; a stand-in result has the size of a real one (its outputs and the
    # request's columns, forwarded).
    res = protocol.result()
    res.run_id, res.discipline, res.flow = "bench", "request", list(DAG)
    res.point_ok = np.ones(1, bool)
    res.outputs = protocol.batch({"motor_kw": np.array([80.0]), "gear_ratio": np.array([7.94]),
                              "battery_kwh": np.array([24.0])})
    got = []

    def on(data, _info):
        got.append(protocol.from_named_array(protocol.decode_result(data).outputs) if mode == "codec" else data)

    pairs = [(s, on) for s in subs]
    waiter = MultiWaiter(ctx)
    pids = [c.pid for c in children] + [os.getpid()]
    lat = []
    for i in range(n + 100):
        if i == 100:
            cpu0 = [cpu_s(p) for p in pids]
        got.clear()
        t0 = time.perf_counter()
        res.evaluation_id = i
        pub.publish(protocol.encode_result(res))
        while len(got) < len(subs):
            if not waiter.wait(subs, 5.0):
                raise RuntimeError(f"the {mode} stand-in processes stopped answering")
            waiter.take_ready(pairs)
        if i >= 100:
            lat.append(time.perf_counter() - t0)
    cpu = [(cpu_s(p) - c) / n for p, c in zip(pids, cpu0)]
    if mode == "codec":  # the stand-ins computed the real thing: range from energy from mass
        ranges = [g["range_km"][0] for g in got if "range_km" in g]
        assert len(ranges) == 1 and 100.0 < ranges[0] < 1000.0, ranges
    for c in children:
        c.terminate()
        c.wait()
    node.destroy_node()
    return lat, cpu


def cpu_s(pid: int) -> float:
    """CPU seconds of every thread of a process so far (/proc/<pid>/task/*/schedstat, ns exact;
    /proc/<pid>/stat counts whole clock ticks and overstates short bursts several times)."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total += int((task / "schedstat").read_text().split()[0])
        except (FileNotFoundError, ProcessLookupError):
            pass  # a thread that ended meanwhile
    return total / 1e9


def pct(a, q):
    return float(np.percentile(np.asarray(a) * 1e6, q))


def ping_pong(ctx, env, n):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from bev_mdo import protocol
    from bev_mdo.ros.common import REQUEST_QOS, RESULT_QOS
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult

    child = subprocess.Popen([sys.executable, "-c", ECHO], env=env)
    node = Node("bench_ping", context=ctx)
    got = []
    pub = node.create_publisher(EvaluationRequest, "/bench/ping", REQUEST_QOS)
    sub = node.create_subscription(EvaluationResult, "/bench/pong", lambda m: got.append(m), RESULT_QOS)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    while pub.get_subscription_count() < 1 or sub.get_publisher_count() < 1:
        ex.spin_once(timeout_sec=0.05)
    req = EvaluationRequest()
    protocol.to_named_array({"motor_kw": np.array([80.0]), "gear_ratio": np.array([8.0])}, req.inputs)
    lat = []
    for i in range(n + 50):
        got.clear()
        req.evaluation_id = i
        t0 = time.perf_counter()
        pub.publish(req)
        while not got:
            ex.spin_once(timeout_sec=1.0)
        if i >= 50:
            lat.append(time.perf_counter() - t0)
    child.terminate()
    child.wait()
    ex.shutdown()
    node.destroy_node()
    return lat


def main() -> int:
    global DOMAIN
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=2000, help="round trips / evaluations per latency figure")
    ap.add_argument("--json", default=None, help="results file (default bench/results/ros.json)")
    ap.add_argument("--domain-id", type=int, default=None, help=f"ROS domain (default {DOMAIN})")
    args = ap.parse_args()
    DOMAIN = args.domain_id if args.domain_id is not None else DOMAIN
    os.environ["ROS_DOMAIN_ID"] = str(DOMAIN)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy

    from bev_mdo.config import load_config, resolve_disciplines, run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.ros.coordinator_node import CoordinatorNode, discipline_names
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.testing import ros_env

    cfg_path = str(REPO / "config" / "leaf_nedc.yaml")
    config = load_config(cfg_path)
    env = ros_env(DOMAIN)
    figures = {}
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    launcher = Launcher(env)
    try:
        lat = ping_pong(ctx, env, args.n)
        figures["raw_ping_pong_us"] = {"p50": pct(lat, 50), "p99": pct(lat, 99), "n": len(lat)}
        lat = lean_ping_pong(ctx, env, args.n)
        figures["lean_raw_cdr_ping_pong_us"] = {"p50": pct(lat, 50), "p99": pct(lat, 99), "n": len(lat)}
        notes = {"echo": "the data-flow graph's messages through 6 echo processes (no decode, no compute): "
                         "the transport's share",
                 "compute": "the same, each process also running its discipline's compute() on fixed inputs",
                 "codec": "each process decodes, computes on the decoded columns and encodes; no protocol "
                          "(ids, validation, failed points): the least a Python node can do"}
        for mode in FLOOR_MODES:
            lat, cpu = mda_floor(ctx, env, args.n, mode, cfg_path)
            figures[f"floor_{mode}_mda_us"] = {"p50": pct(lat, 50), "p99": pct(lat, 99), "n": len(lat),
                                               "cpu_us_per_mda_total": round(sum(cpu) * 1e6), "note": notes[mode]}
        for name in discipline_names(config):
            launcher.add(name, discipline_argv(name, cfg_path))
        node = CoordinatorNode(config, context=ctx, node_name="bench_coordinator")
        node.evaluator.wait_for_disciplines(discipline_names(config), 60.0)
        form = build_formulation(run_settings(config), node.evaluator)
        x = form.x0[None, :]
        for _ in range(50):
            form.analyse(x)
        lat = []
        pids = {n.label: n.proc.pid for n in launcher.nodes}
        cpu0 = {k: cpu_s(p) for k, p in pids.items()} | {"coordinator": cpu_s(os.getpid())}
        flows0 = node.evaluator.flows
        for _ in range(args.n):
            t0 = time.perf_counter()
            form.analyse(x)
            lat.append(time.perf_counter() - t0)
        cpu1 = {k: cpu_s(p) for k, p in pids.items()} | {"coordinator": cpu_s(os.getpid())}
        cpu = {k: (cpu1[k] - cpu0[k]) / len(lat) * 1e6 for k in cpu0}
        figures["ros_mda_one_point_us"] = {"p50": pct(lat, 50), "p99": pct(lat, 99), "n": len(lat),
                                           "data_flow_requests": node.evaluator.flows - flows0,
                                           "processes": len(launcher.nodes),
                                           "cpu_us_per_mda": {k: round(v) for k, v in cpu.items()},
                                           "cpu_us_per_mda_total": round(sum(cpu.values())),
                                           "host_cpus": os.cpu_count(), "load_average_1min": os.getloadavg()[0]}
        rng = np.random.default_rng(0)
        lo, hi = form.lower, form.upper
        for n in (1_000, 10_000, 100_000):
            X = lo + (hi - lo) * rng.random((n, len(lo)))
            form.analyse(X)
            reps = []
            for _ in range(5):
                t0 = time.perf_counter()
                res = form.analyse(X)
                reps.append(time.perf_counter() - t0)
            assert res.ok.all()
            figures[f"ros_batch_{n}_designs_per_s"] = n / float(np.median(reps))
        node.evaluator.close()
        node.destroy_node()
        local = build_formulation(config, InProcessEvaluator(resolve_disciplines(config)))
        lat = []
        for _ in range(args.n):
            t0 = time.perf_counter()
            local.analyse(x)
            lat.append(time.perf_counter() - t0)
        figures["inprocess_mda_one_point_us"] = {"p50": pct(lat, 50), "p99": pct(lat, 99)}
    finally:
        launcher.stop()
        rclpy.shutdown(context=ctx)
    print(json.dumps(figures, indent=2))
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _results

    figs = []
    for key, what in (("raw_ping_pong_us", "raw rclpy ping-pong (typed messages, executor, two processes)"),
                      ("lean_raw_cdr_ping_pong_us", "the same exchange as raw CDR bytes through one rcl wait set"),
                      ("floor_echo_mda_us", "floor 1, transport: one data-flow MDA's messages through 6 echo processes"),
                      ("floor_compute_mda_us", "floor 2: the same, each process also running compute()"),
                      ("floor_codec_mda_us", "floor 3: decode + compute + encode in each process"),
                      ("ros_mda_one_point_us", "one full MDA over ROS (1 point, 6 discipline processes)"),
                      ("inprocess_mda_one_point_us", "one full MDA in process")):
        if key in figures:
            figs.append(_results.figure(f"{what}, p50 over {args.n}", "µs", [figures[key]["p50"]],
                                        "<= 1000" if key == "ros_mda_one_point_us" else None))
            figs.append(_results.figure(f"{what}, p99 over {args.n}", "µs", [figures[key]["p99"]]))
    if "ros_mda_one_point_us" in figures:
        figs.append(_results.figure("CPU one MDA over ROS costs (all processes)", "µs",
                                    [figures["ros_mda_one_point_us"]["cpu_us_per_mda_total"]]))
    for n in (1_000, 10_000, 100_000):
        if f"ros_batch_{n}_designs_per_s" in figures:
            figs.append(_results.figure(f"batched throughput over ROS, {n} points per batch (median of 5)",
                                        "designs/s", [figures[f"ros_batch_{n}_designs_per_s"]], ">= 50000"))
    _results.write("ros", figs, path=args.json, extra={"raw": figures})
    return 0


if __name__ == "__main__":
    sys.exit(main())
