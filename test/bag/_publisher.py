"""Test helper process: publishes IterationRecords in batches, one batch per stdin line.

Usage: python _publisher.py BATCH_SIZE N_BATCHES. Prints "ready" after discovery and
"sent K" after each batch has been acknowledged by the subscriber (the recorder).
"""
import sys

import rclpy
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from bev_mdo_msgs.msg import IterationRecord, NamedArray


def record(i: int) -> IterationRecord:
    msg = IterationRecord(run_id="rec-test", sequence=i, iteration=i, formulation="mdf",
                          optimizer="SLSQP", objective=1000.0 - i, feasible=bool(i % 2))
    msg.design = NamedArray(names=["motor_kw", "battery_kwh"], batch_size=1,
                            values=[50.0 + 0.25 * i, 40.0 + 0.5 * i])
    return msg


def main() -> int:
    batch, n_batches = int(sys.argv[1]), int(sys.argv[2])
    rclpy.init()
    node = Node("test_publisher")
    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                     depth=batch * n_batches)
    pub = node.create_publisher(IterationRecord, "/bev_mdo/iteration", qos)
    while pub.get_subscription_count() < 1:
        rclpy.spin_once(node, timeout_sec=0.05)
    print("ready", flush=True)
    i = 0
    for _ in range(n_batches):
        if not sys.stdin.readline():
            break
        for _ in range(batch):
            pub.publish(record(i))
            i += 1
        pub.wait_for_all_acked(Duration(seconds=30))
        print(f"sent {i}", flush=True)
    sys.stdin.readline()
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
