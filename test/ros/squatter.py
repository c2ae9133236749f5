"""A squatter on a run's topics: ``python squatter.py NODE_NAME pub|sub TOPIC [TOPIC ...]`` creates a node
named NODE_NAME that subscribes to (``sub``) or publishes on (``pub``, once a second) every TOPIC with the
wrong type (std_msgs/msg/String), prints ``ready`` and spins until stopped (SIGINT or stdin closed)."""
from __future__ import annotations

import sys
import threading

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String


def main() -> int:
    name, kind, topics = sys.argv[1], sys.argv[2], sys.argv[3:]
    rclpy.init()
    node = rclpy.create_node(name)
    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=10)
    if kind == "sub":
        ends = [node.create_subscription(String, t, lambda m: None, qos) for t in topics]
    else:
        ends = [node.create_publisher(String, t, qos) for t in topics]
        node.create_timer(1.0, lambda: [p.publish(String(data="squatting")) for p in ends])
    print("ready", flush=True)
    threading.Thread(target=lambda: (sys.stdin.read(), rclpy.try_shutdown()), daemon=True).start()
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
