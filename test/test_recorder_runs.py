"""A run's recorder keeps its own run's node counters only: with eight runs on one domain a bag held 250
/bev_mdo/node_stats messages, 190 of them from the 7 other runs' nodes (docs/recording.md: a bag holds
its own run only). The nodes now name their run in their counters, and the recorder drops (and counts)
those of another run or of none, as it drops other runs' requests, results and iteration records.
No ROS graph: the recorder's message handler and the node's publisher are called on stand-ins."""
from __future__ import annotations

import json
from types import SimpleNamespace

RUN = "f3f8b78c0a1b2c3d"


def _stats(**fields) -> bytes:
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    return serialize_message(String(data=json.dumps({"discipline": "vehicle_mass", "instance": "vehicle_mass_node",
                                                     "counts": {"requests": 3}, "host": "h", "pid": 1, **fields})))


def _recorder(run_id: str):
    written = []
    return written, SimpleNamespace(run_id=run_id, order=None, other_run=0, received=0,
                                    writer=SimpleNamespace(write=lambda topic, data, *a: written.append(data)))


def test_a_runs_recorder_keeps_only_its_own_runs_node_stats():
    from bev_mdo.ros.common import NODE_STATS_TOPIC
    from bev_mdo.ros.recorder_node import RecorderNode

    written, rec = _recorder(RUN)
    on_message = RecorderNode._callback(rec, NODE_STATS_TOPIC, "std_msgs/msg/String")
    own = [_stats(run_id=RUN), _stats(run_id=f"{RUN}-baseline")]  # the run and its sub-runs
    others = [_stats(run_id="0123456789abcdef"), _stats(run_id=f"{RUN[:8]}ffffffff"), _stats(run_id=""), _stats(),
              _stats(run_id=7)]
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    others.append(serialize_message(String(data="not JSON")))
    for data in (others[0], *own, *others[1:]):
        on_message(data, {})
    assert written == own
    assert rec.other_run == len(others) and rec.received == len(own)
    # `bev-mdo record` (no --run-id) records the domain as it is
    written, rec = _recorder("")
    on_message = RecorderNode._callback(rec, NODE_STATS_TOPIC, "std_msgs/msg/String")
    for data in (_stats(run_id=RUN), _stats(run_id="0123456789abcdef"), _stats()):
        on_message(data, {})
    assert len(written) == 3 and rec.other_run == 0


def test_a_bound_node_names_its_run_in_its_counters():
    from bev_mdo.ros.discipline_node import DisciplineNode

    sent = []
    node = SimpleNamespace(counts={"requests": 2}, _stats_t=0.0, _stats_sent=None, discipline_name="vehicle_mass",
                           instance="vehicle_mass_node_f3f8b78c", compute_s=0.5, bound_run=RUN,
                           fingerprint="0123456789abcdef", _stats_pub=SimpleNamespace(publish=sent.append))
    DisciplineNode.publish_stats(node, force=True)
    sent_stats = json.loads(sent[0].data)
    assert (sent_stats["run_id"], sent_stats["fingerprint"]) == (RUN, "0123456789abcdef")  # status shows its own


def test_a_runs_recorder_keeps_only_its_own_runs_pareto_fronts():
    """A pareto run's bag kept every run's /bev_mdo/pareto_front: another pareto run on the domain added its
    generations to the bag's (a test saw generations 1, 2, 3 followed by another run's 1, 2, 3)."""
    from rclpy.serialization import serialize_message

    from bev_mdo.ros.recorder_node import RecorderNode
    from bev_mdo_msgs.msg import ParetoFront

    written, rec = _recorder(RUN)
    on_message = RecorderNode._callback(rec, "/bev_mdo/pareto_front", "bev_mdo_msgs/msg/ParetoFront")
    own = [serialize_message(ParetoFront(run_id=RUN, generation=g)) for g in (1, 2)]
    other = serialize_message(ParetoFront(run_id="0123456789abcdef", generation=1))
    for data in (own[0], other, own[1]):
        on_message(data, {})
    assert written == own and rec.other_run == 1
