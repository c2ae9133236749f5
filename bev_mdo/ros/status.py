"""Live discipline instances on a ROS domain, for `bev-mdo status`. Listens a while to the discipline
declarations (/bev_mdo/discipline_info, kept for late joiners) and node counters (/bev_mdo/node_stats: host,
pid, points answered, compute time), and checks the ROS graph for who still reads its request topic.
Throughput: points per second of compute time since the node started (its capacity), and points answered
per second of the listening window (its load: 0 when idle; a node's first counters are its latest, kept for
late joiners, so they are its count when the window opened). Two processes of one node name: a row each, with
its own run and fingerprint (protocol/node_stats.status_row).
"""
from __future__ import annotations

import json
import time
from collections import Counter

from bev_mdo.ros.common import (DECLARATION_READER_QOS, INFO_TOPIC, NODE_STATS_READER_QOS, NODE_STATS_TOPIC,
                                request_topic)
from bev_mdo.protocol.node_stats import status_row
from bev_mdo.ros.fastwait import until


def collect(node, listen_s: float = 2.0) -> list[dict]:
    """[{discipline, instance, host, pid, live, run_id, fingerprint, points, compute_s, ...}] sorted."""
    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from bev_mdo_msgs.msg import DisciplineInfo

    infos: dict[tuple[str, str], DisciplineInfo] = {}
    first: dict[tuple, dict] = {}  # (instance, host, pid) -> the first and the last counters it sent while we
    last: dict[tuple, dict] = {}  # listened: two processes given one node name stay apart

    def on_info(msg):
        infos[(msg.discipline, msg.instance.lstrip("/"))] = msg

    def on_stats(msg):
        d = json.loads(msg.data)
        key = (str(d.get("instance", "")).lstrip("/"), d.get("host"), d.get("pid"))
        first.setdefault(key, d)
        last[key] = d

    subs = [node.create_subscription(DisciplineInfo, INFO_TOPIC, on_info, DECLARATION_READER_QOS),
            node.create_subscription(String, NODE_STATS_TOPIC, on_stats, NODE_STATS_READER_QOS)]
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    try:
        deadline = time.monotonic() + listen_s
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        rows = []
        disciplines = {d for d, _ in infos} | {s.get("discipline", "") for s in last.values()}
        for disc in sorted(x for x in disciplines if x):
            readers = node.get_subscriptions_info_by_topic(request_topic(disc))
            graph = {f"{r.node_namespace.rstrip('/')}/{r.node_name}".lstrip("/") for r in readers}
            graph |= {r.node_name for r in readers}
            names = {i for d, i in infos if d == disc} | {k[0] for k, s in last.items() if s.get("discipline") == disc}
            for inst, key in [(i, k) for i in sorted(names) for k in sorted((k for k in last if k[0] == i), key=str)
                              or [None]]:
                rows.append(status_row(disc, inst, inst in graph, infos.get((disc, inst)), first.get(key),
                                       last.get(key), listen_s))
        return rows
    finally:
        executor.remove_node(node)
        executor.shutdown()
        for s in subs:
            node.destroy_subscription(s)


class NodeStatsListener:
    """Latest counters of every discipline node (from /bev_mdo/node_stats), by instance name."""

    def __init__(self, node):
        from rclpy.executors import SingleThreadedExecutor
        from std_msgs.msg import String

        self.node = node
        self.latest: dict[str, dict] = {}
        self._sub = node.create_subscription(String, NODE_STATS_TOPIC, self._on_stats, NODE_STATS_READER_QOS)
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)

    def _on_stats(self, msg) -> None:
        d = json.loads(msg.data)
        self.latest[d["instance"]] = d

    def seen(self, discipline: str) -> bool:
        """True once any instance of `discipline` published its counters."""
        return any(d["discipline"] == discipline for d in self.latest.values())

    def counts(self, discipline: str | None = None) -> Counter:
        """Counters summed over instances (of one discipline, or of all)."""
        total: Counter[str] = Counter()
        for d in self.latest.values():
            if discipline is None or d["discipline"] == discipline:
                total.update(d["counts"])
        return total

    def wait(self, predicate, timeout_s: float) -> bool:
        """Spin until `predicate(self)` holds; False after `timeout_s`."""
        return until(lambda: predicate(self), timeout_s, lambda: self._executor.spin_once(timeout_sec=0.05))

    def close(self) -> None:
        self._executor.remove_node(self.node)
        self._executor.shutdown()
        self.node.destroy_subscription(self._sub)
