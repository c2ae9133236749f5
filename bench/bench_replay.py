"""Benchmark: replay as fast as possible (target >= 20 000 messages/s) and bag size per message.

Writes a synthetic bag (requests, results, iteration records like a real MDF run), then
publishes it with the replay publisher as fast as possible into one raw subscriber in a
second process, and prints: write rate, bytes per message and per multidisciplinary
evaluation, publish rate, and how many messages the subscriber got.

    . scripts/env.sh && ROS_DOMAIN_ID=49 python bench/bench_replay.py [--iterations N]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "test" / "bag"))

SUBSCRIBER = r"""
import sys, time, rclpy
from rclpy.node import Node
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from bev_mdo.ros.recorder_node import message_class
rclpy.init()
node = Node("bench_sub")
n = [0]
qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=100000)
for arg in sys.argv[2:]:
    topic, type_name = arg.split("=")
    node.create_subscription(message_class(type_name), topic, lambda d: n.__setitem__(0, n[0] + 1), qos, raw=True)
ex = SingleThreadedExecutor(); ex.add_node(node)
print("ready", flush=True)
expected = int(sys.argv[1]); t_first = None
deadline = time.monotonic() + 120
while n[0] < expected and time.monotonic() < deadline:
    ex.spin_once(timeout_sec=0.1)
    if n[0] and t_first is None: t_first = time.monotonic()
print(n[0], flush=True)
"""


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=5000)
    parser.add_argument("--no-subscriber", action="store_true", help="publish with nobody listening")
    parser.add_argument("--json", default=None, help="results file (default bench/results/replay.json)")
    args = parser.parse_args()
    os.environ.setdefault("ROS_DOMAIN_ID", "49")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    os.environ.setdefault("AMENT_PREFIX_PATH", str(ROOT / ".venv"))
    from rclpy.serialization import serialize_message

    from conftest import DISCIPLINES, synthetic

    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.writer import BagWriter
    from bev_mdo.ros import replay as rp

    msgs = [(t, ty, serialize_message(m)) for t, ty, m in synthetic(args.iterations)]
    with tempfile.TemporaryDirectory() as tmp:
        bag_dir = Path(tmp) / "bench"
        t = time.perf_counter()
        with BagWriter(bag_dir, metadata={"config_yaml": "bench: true\n"}) as writer:
            for j, (topic, type_name, data) in enumerate(msgs):
                writer.add_topic(topic, type_name)
                writer.write(topic, data, j * 1000, j * 1000)
        write_s = time.perf_counter() - t
        size = (bag_dir / "bench_0.mcap").stat().st_size
        n = len(msgs)
        evaluations = args.iterations  # one MDA (all disciplines) per iteration here
        print(f"messages: {n} ({args.iterations} iterations x {len(DISCIPLINES)} disciplines)")
        print(f"write: {n / write_s:,.0f} msg/s")
        print(f"bag size: {size} bytes = {size / n:.1f} B/message = "
              f"{size / evaluations:.1f} B per multidisciplinary evaluation "
              f"(raw CDR {sum(len(d) for *_, d in msgs) / n:.1f} B/message)")

        bag = open_bag(bag_dir)
        sub = None
        if not args.no_subscriber:
            sub = subprocess.Popen([sys.executable, "-c", SUBSCRIBER, str(n),
                                    *[f"{t}={ty}" for t, ty in bag.topics.items()]],
                                   stdout=subprocess.PIPE, text=True, env=dict(os.environ))
            assert sub.stdout.readline().strip() == "ready"
        import rclpy
        from rclpy.node import Node

        context = rclpy.context.Context()
        rclpy.init(context=context)
        node = Node("bench_replay", context=context)
        t = time.perf_counter()
        player = rp.Replayer(node, bag)
        load_s = time.perf_counter() - t
        if sub:
            player.wait_subscribers(1, 30)
        stats = player.play(rate=None)
        acked = time.perf_counter()
        if sub:
            player.wait_acked(60)
        acked = time.perf_counter() - acked
        print(f"read+decompress bag: {n / load_s:,.0f} msg/s")
        print(f"replay publish (as fast as possible): {stats.messages_per_s:,.0f} msg/s "
              f"({stats.messages} in {stats.seconds:.3f} s; target >= 20,000)")
        if sub:
            got = int(sub.communicate(timeout=180)[0].strip().splitlines()[-1])
            print(f"subscriber received {got}/{n} (all acknowledged {acked:.3f} s after the last publish)")
        node.destroy_node()
        rclpy.shutdown(context=context)
    sys.path.insert(0, str(ROOT / "bench"))
    import _results

    _results.write("replay", [
        _results.figure("replay as fast as possible, publish rate", "messages/s", [stats.messages_per_s], ">= 20000"),
        _results.figure("bag write rate", "messages/s", [n / write_s]),
        _results.figure("read + decompress the bag", "messages/s", [n / load_s]),
        _results.figure("bag size per message (synthetic MDF traffic)", "B", [size / n])], path=args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
