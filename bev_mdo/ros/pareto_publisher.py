"""ParetoFront messages of ``bev-mdo pareto``: built from a ``mdo.pareto.Front``, published on
/bev_mdo/pareto_front by the coordinator side (over ROS, so the recorder writes them into the
run's bag), or written straight into a bag with ``BagWriter`` (in process)."""
from __future__ import annotations

import json
from typing import Callable

import numpy as np
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from bev_mdo import interrupts
from bev_mdo.ros.common import PREFIX, now_ns, stamp, wait_acked
from bev_mdo.ros.fastwait import until

PARETO_TOPIC = f"{PREFIX}/pareto_front"
PARETO_TYPE = "bev_mdo_msgs/msg/ParetoFront"
# One message per generation per topology; deep enough that none is overwritten before the
# recorder acknowledged it (a run is tens of generations, four topologies at most).
PARETO_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=4096,
                        durability=DurabilityPolicy.VOLATILE)


def front_columns(front) -> dict[str, np.ndarray]:
    """The front's columns: design variables first, then every other MDA variable by name."""
    cols = {n: np.asarray(front.values[n], float) if n in front.values else front.X[:, j]
            for j, n in enumerate(front.names)}
    cols.update({k: np.asarray(front.values[k], float) for k in sorted(front.values) if k not in cols})
    return cols


def front_message(front, *, run_id: str, topology: str, final: bool):
    """A ParetoFront message of one generation's front."""
    from bev_mdo import protocol
    from bev_mdo_msgs.msg import ParetoFront

    msg = ParetoFront()
    stamp(msg.header)
    msg.run_id = run_id
    msg.topology = topology
    msg.generation = int(front.generation)
    msg.final = bool(final)
    msg.objectives = list(front.objectives)
    protocol.to_named_array(front_columns(front), msg.designs)
    msg.evaluations = int(front.evaluations)
    msg.wall_time_s = float(front.wall_time_s)
    return msg


class BagSink:
    """In process: ParetoFront messages serialised (CDR) straight into a new bag."""

    def __init__(self, bag_dir, metadata: dict[str, str]):
        from bev_mdo.bag.writer import BagWriter

        self.writer = BagWriter(bag_dir, metadata=metadata)
        self.writer.add_topic(PARETO_TOPIC, PARETO_TYPE, PARETO_QOS)
        self.published = 0

    def publish(self, msg) -> None:
        from rclpy.serialization import serialize_message

        t = now_ns()
        with interrupts.deferred():  # a front is written whole or not at all
            self.writer.write(PARETO_TOPIC, serialize_message(msg), t, t, self.published + 1)
            self.writer.flush()  # one chunk per front: a killed run keeps every finished generation
            self.published += 1

    def close(self) -> None:
        self.writer.close()


class RosSink:
    """Over ROS: a small node publishing ParetoFront messages for the recorder, and following the
    study's own recorder by its declaration (recorder_node.OwnRecorder)."""

    def __init__(self, context, run_id: str, node_name: str = "pareto_publisher", signer=None,
                 binding: str | None = None):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node

        from bev_mdo.ros.recorder_node import OwnRecorder
        from bev_mdo_msgs.msg import ParetoFront

        self.run_id = run_id
        self.node = Node(node_name, context=context)
        self.pub = self.node.create_publisher(ParetoFront, PARETO_TOPIC, PARETO_QOS)
        self.recorder = OwnRecorder(self.node, run_id, signer, binding)  # the study's recorder, by its declaration
        self.executor = SingleThreadedExecutor(context=context)
        self.executor.add_node(self.node)
        self.published = 0

    def spin(self, timeout_s: float) -> None:
        """Take the recorder's declarations for up to ``timeout_s``."""
        self.executor.spin_once(timeout_sec=timeout_s)

    def wait_for_recorder(self, wait_s: float, gone=None) -> None:
        """Wait until the study's own recorder (its declaration) reads the front topic and matched this
        publisher, so the first front is recorded; ValueError once nothing changed for `wait_s`, or as soon
        as `gone()` says why the recorder's process ended (sessions.recorder_gone)."""
        rec = self.recorder
        ready = until(lambda: rec.records(PARETO_TOPIC, pub=self.pub) or bool(gone and gone()), wait_s,
                      lambda: self.spin(0.02),
                      lambda: (json.dumps(rec.declaration, sort_keys=True), tuple(sorted(self.node.get_node_names()))),
                      f"the study's recorder on {PARETO_TOPIC}")
        why = gone() if gone is not None and not rec.records(PARETO_TOPIC, pub=self.pub) else None
        if why or not ready:  # its process ended, or nothing changed
            raise ValueError(f"the study's recorder {why}" if why else f"the study's recorder did not "
                             f"{'match' if rec.declaration else 'declare itself on'} {PARETO_TOPIC}; nothing "
                             f"changed for {wait_s:g} s")

    def publish(self, msg) -> None:
        self.published += 1
        self.pub.publish(msg)

    def wait_for_all_acked(self, wait_s: float, give_up: Callable[[], bool] | None = None,
                           slice_s: float = 0.05) -> bool:
        """Block until every reader (the recorder) acknowledged every front published; False after
        `wait_s`, or at once when `give_up()` says the reader that matters is dead (a killed reader
        stays matched until its lease expires)."""
        return not wait_acked([self.pub], wait_s, give_up, slice_s)

    def close(self) -> None:
        self.executor.remove_node(self.node)
        self.executor.shutdown()
        self.node.destroy_node()
