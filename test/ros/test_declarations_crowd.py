"""A crowded domain: many runs' recorders and disciplines declare themselves (TRANSIENT_LOCAL, once, or
again only when something changed) on one topic each. A coordinator may take them only after a burst
of others' declarations arrived behind its own; its own must be kept, not overwritten by them (a
reader's history is one queue for every writer of the topic)."""
from __future__ import annotations

import json

from bev_mdo.testing import wait_until

CROWD = 100  # declarations of other runs behind this run's own: a dozen Leaf runs' disciplines


def _all_acked(pubs) -> bool:
    from rclpy.duration import Duration

    return all(p.wait_for_all_acked(Duration(seconds=30)) for p in pubs)


def test_a_runs_recorder_declaration_survives_other_recorders_declaring_before_it_is_read(rclpy_context):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from std_msgs.msg import String

    from bev_mdo.ros.recorder_node import STATUS_QOS, STATUS_TOPIC, OwnRecorder

    def declaration(run):
        text = json.dumps({"run_id": run, "recorder": f"/recorder_{run}", "publishers": {}}, sort_keys=True)
        return String(data=json.dumps({"declaration": text, "signature": ""}))

    coordinator = Node("crowd_coordinator", context=rclpy_context)
    own = OwnRecorder(coordinator, "r1", None, None)
    recorders = Node("crowd_recorders", context=rclpy_context)
    pubs = [recorders.create_publisher(String, STATUS_TOPIC, STATUS_QOS) for _ in range(8)]  # as recorder_node's
    ex = SingleThreadedExecutor(context=rclpy_context)
    ex.add_node(coordinator)
    try:
        assert wait_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs), step=lambda: ex.spin_once(0.02)), \
            "timed out waiting for the status writers to match"
        pubs[0].publish(declaration("r1"))  # this run's recorder, then seven others, none taken yet
        for k, p in enumerate(pubs[1:], 2):
            p.publish(declaration(f"r{k}"))
        assert _all_acked(pubs), "the coordinator's reader did not acknowledge every declaration"
        assert wait_until(lambda: sum(own.dropped.values()) >= 7, step=lambda: ex.spin_once(0.02)), \
            f"declarations taken: {dict(own.dropped)}"
        assert own.name == "/recorder_r1"
        assert own.dropped == {"recorder_other_run": 7}
    finally:
        ex.shutdown()
        coordinator.destroy_node()
        recorders.destroy_node()


def test_a_runs_discipline_declaration_survives_a_crowd_declared_before_the_coordinator_started(rclpy_context):
    from rclpy.node import Node

    from bev_mdo.ros.common import INFO_QOS, INFO_TOPIC
    from bev_mdo.ros.evaluator import RosEvaluator
    from bev_mdo.binding import fingerprint_of_json
    from bev_mdo_msgs.msg import DisciplineInfo

    def info(run: str, k: int) -> DisciplineInfo:
        msg = DisciplineInfo()
        msg.discipline, msg.instance, msg.run_id = "energy", f"/energy_node_{run}_{k}", run
        msg.inputs, msg.outputs = ["vehicle_mass_kg"], ["energy_wh_per_km"]
        msg.effective_config = "{}"
        msg.fingerprint = fingerprint_of_json(msg.effective_config)
        return msg

    disciplines = Node("crowd_disciplines", context=rclpy_context)
    pubs = [disciplines.create_publisher(DisciplineInfo, INFO_TOPIC, INFO_QOS) for _ in range(CROWD + 1)]
    pubs[0].publish(info("r1", 0))  # this run's node declared first, then the crowd (as discipline_node's)
    for k, p in enumerate(pubs[1:], 1):
        p.publish(info("r2", k))
    coordinator = Node("crowd_coordinator_info", context=rclpy_context)
    ev = RosEvaluator(coordinator, run_id="r1")
    try:
        # the late reader gets every writer's history (TRANSIENT_LOCAL) before it takes any
        assert wait_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs)), \
            "timed out waiting for the coordinator to match every declaration writer"
        assert _all_acked(pubs), "the coordinator's reader did not acknowledge every declaration"
        assert wait_until(lambda: ev.dropped["info_other_run"] >= CROWD, step=lambda: ev.spin(0.02)), \
            f"declarations taken: {dict(ev.dropped)}"
        assert ev.instances == {"energy": {"energy_node_r1_0"}}
        assert ev.dropped["info_other_run"] == CROWD
    finally:
        ev.close()
        coordinator.destroy_node()
        disciplines.destroy_node()
