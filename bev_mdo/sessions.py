"""Sessions of a multi-run study (``bev-mdo pareto``, bench/bench_pareto.py): where its evaluators
come from and where its ParetoFront messages go.

* ``ParetoInProcessSession``: in-process evaluators; the fronts go straight into a bag (BagSink).
* ``ParetoRosSession``: as ``bev-mdo optimize`` runs over ROS: a recorder node writing the bag for
  the whole session, one set of discipline nodes and one coordinator per topology, signed with a
  per-run key by default (docs/security.md).

ROS is imported only when a ROS session starts.
"""
from __future__ import annotations

import contextlib
import time
from pathlib import Path

from bev_mdo.config import plain


class _InProcess:
    """The in-process evaluator of one topology, closed on exit."""

    def __init__(self, cfg):
        from bev_mdo.config import resolve_disciplines
        from bev_mdo.mdo.evaluator import InProcessEvaluator

        self.ev = InProcessEvaluator(resolve_disciplines(cfg))

    def __enter__(self):
        return self.ev

    def __exit__(self, *exc):
        self.ev.close()


class ParetoInProcessSession:
    """In process: the fronts go straight into ``<out>/bag`` (BagWriter)."""

    def __init__(self, raw, bag: Path, run_id: str):
        import yaml

        from bev_mdo.ros.pareto_publisher import BagSink

        self.sink = BagSink(bag, {"run_id": run_id, "config_yaml": yaml.safe_dump(plain(raw), sort_keys=False)})
        self.stats = {}

    def evaluator(self, cfg, topology):
        return _InProcess(cfg)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.sink.close()


class ParetoRosSession:
    """Over ROS, as ``bev-mdo optimize`` does it: a recorder node writing ``<out>/bag`` for the
    whole run, one set of discipline nodes per topology (the previous set is stopped first: the
    nodes of two topologies answer the same topics), a coordinator (its RosEvaluator) per topology
    and one ParetoFront publisher; the recorder is stopped first, after it acknowledged every front."""

    def __init__(self, raw, ros: dict, out: Path, bag: Path, run_id: str):
        self.raw, self.ros, self.out, self.bag, self.run_id = raw, dict(ros), out, bag, run_id
        self.stats = {"dropped_messages": {}, "retried_requests": 0}
        self.labels: list[str] = []
        self.launcher = self.ctx = self.sink = None

    def __enter__(self):
        import rclpy
        import yaml

        from bev_mdo.ros.client import apply_ros_environment
        from bev_mdo.ros.launch import Launcher, start_recorder
        from bev_mdo.ros.pareto_publisher import RosSink
        from bev_mdo.ros.settings import ros_environment

        apply_ros_environment(self.ros)
        self.logs = self.out / ".logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        from bev_mdo.ros.auth import with_run_key

        self.ros = with_run_key({"ros": self.ros}, self.logs)["ros"]  # signed by default (docs/security.md)
        resolved = self.logs / "config.yaml"
        resolved.write_text(yaml.safe_dump(plain({**self.raw, "ros": self.ros}), sort_keys=False))
        self.launcher = Launcher(ros_environment(self.ros), log_dir=self.logs)
        try:
            self.recorder = start_recorder(self.launcher, self.bag, resolved, self.run_id)
            self.launcher.supervise()
            self.ctx = rclpy.context.Context()
            rclpy.init(context=self.ctx)
            self.sink = RosSink(self.ctx, self.run_id)
            self.sink.wait_for_recorder(self.recorder, self.ros["discovery_wait_s"])
        except BaseException:
            self.__exit__()
            raise
        return self

    @contextlib.contextmanager
    def evaluator(self, cfg, topology):
        import yaml

        from bev_mdo.config import discipline_entries
        from bev_mdo.ros import coordinator_node
        from bev_mdo.ros.launch import discipline_argv

        cfg = {**cfg, "ros": self.ros}
        wait_s = self.ros["discovery_wait_s"]
        names = coordinator_node.discipline_names(cfg)
        self._stop_disciplines(names, wait_s)
        logs = self.logs / topology
        logs.mkdir(parents=True, exist_ok=True)
        resolved = logs / "config.yaml"
        resolved.write_text(yaml.safe_dump(plain(cfg), sort_keys=False))
        for entry in discipline_entries(cfg):
            label = f"{topology}/{entry['name']}"
            self.launcher.add(label, discipline_argv(entry["name"], str(resolved.resolve()),
                                                     run_id=f"{self.run_id}-{topology}"))
            self.labels.append(label)
        node = coordinator_node.CoordinatorNode(cfg, f"{self.run_id}-{topology}", context=self.ctx)
        try:
            node.evaluator.wait_for_disciplines(names, wait_s, extra_subscribers=self.recorder)
            node.wait_for_recorder(self.recorder, wait_s)
            self._wait_recorder_topics([f"{n}_node" for n in names], wait_s)
            node.evaluator.warm_up(names)
            yield node.evaluator
            for k, v in node.evaluator.dropped.items():
                self.stats["dropped_messages"][k] = self.stats["dropped_messages"].get(k, 0) + v
            self.stats["retried_requests"] += node.evaluator.retried
            # the recorder has every request of this topology and every front so far
            node.wait_for_all_acked(wait_s)
            self.sink.wait_for_all_acked(wait_s)
        finally:
            node.evaluator.close()
            node.destroy_node()

    def _wait_recorder_topics(self, node_names, wait_s: float) -> None:
        """Wait until the recorder's subscriptions matched every publisher these nodes have under
        /bev_mdo/ (their results): a message published before that would be missing from the bag.
        The recorder finds new topics by polling the graph and reports its matches on its status
        topic; a topic's publishers in this process's graph must all be matched there."""
        from rclpy.node import NodeNameNonExistentError

        from bev_mdo.ros.common import PREFIX

        node = self.sink.node
        deadline = time.monotonic() + wait_s
        while True:
            missing = []
            for n in node_names:
                try:
                    topics = [t for t, _ in node.get_publisher_names_and_types_by_node(n, "/")]
                except NodeNameNonExistentError:
                    missing.append(n)
                    continue
                missing += [t for t in topics if t.startswith(PREFIX + "/")
                            and self.sink.recorder_matched.get(t, 0) < node.count_publishers(t)]
            if not missing:
                return
            if time.monotonic() > deadline:
                raise ValueError(f"the recorder did not match the publishers of {missing[0]} within {wait_s:g} s")
            self.sink.spin(0.02)

    def _stop_disciplines(self, names, wait_s: float) -> None:
        """Stop the previous topology's discipline nodes and wait until the graph lost them."""
        for label in self.labels:
            self.launcher.remove(label)
        self.labels = []
        node_names = {f"{n}_node" for n in names}
        deadline = time.monotonic() + wait_s
        while node_names & set(self.sink.node.get_node_names()):
            if time.monotonic() > deadline:
                raise ValueError(f"discipline nodes of the previous topology still on the graph after {wait_s:g} s")
            self.sink.spin(0.02)  # graph polling

    def __exit__(self, *exc):
        import rclpy

        try:
            if self.sink is not None:
                self.sink.wait_for_all_acked(self.ros["discovery_wait_s"])
                self.sink.close()
            if self.ctx is not None:
                rclpy.shutdown(context=self.ctx)
        finally:
            if self.launcher is not None:
                self.launcher.stop(first=("recorder",))
                self.stats["node_restarts"] = {n.label: n.restarts for n in self.launcher.nodes if n.restarts}
