"""The recorder subscribes to a topic only once its publishers are known, with their durability."""
from __future__ import annotations

from bev_mdo.testing import wait_until


def test_a_topic_seen_first_through_its_reader_is_recorded_with_its_publishers_durability(rclpy_context, tmp_path):
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String

    from bev_mdo.ros.recorder_node import RecorderNode

    topic = "/bev_mdo_rectest/late_publisher"
    latched = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=4,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    other = Node("rectest_peer", context=rclpy_context)
    recorder = RecorderNode(context=rclpy_context, node_name="rectest_recorder", parameter_overrides=[
        Parameter("bag_path", value=str(tmp_path / "bag")), Parameter("prefix", value="/bev_mdo_rectest/"),
        Parameter("discovery_period_s", value=3600.0)])  # discover() is called by the test only
    ex = SingleThreadedExecutor(context=rclpy_context)
    ex.add_node(recorder)
    ex.add_node(other)
    try:
        # the consumer comes first: the graph has the topic but no publisher
        other.create_subscription(String, topic, lambda m: None, latched)
        assert wait_until(lambda: topic in dict(recorder.get_topic_names_and_types()), step=lambda: ex.spin_once(0.02)), \
            "timed out waiting for the reader on the graph"
        recorder.discover()
        assert topic not in recorder.subscriptions_by_topic, "subscribed before any publisher was known"
        # the publisher answers before the recorder subscribes (a warm-up result, say)
        pub = other.create_publisher(String, topic, latched)
        pub.publish(String(data="first"))
        assert wait_until(lambda: recorder.get_publishers_info_by_topic(topic), step=lambda: ex.spin_once(0.02)), \
            "timed out waiting for the publisher on the graph"
        recorder.discover()
        sub = recorder.subscriptions_by_topic[topic]
        assert sub.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
        assert wait_until(lambda: recorder.received >= 1, step=lambda: ex.spin_once(0.02)), \
            "timed out waiting for the earlier message"
        assert recorder.received == 1
    finally:
        ex.shutdown()
        recorder.writer.close()
        recorder.destroy_node()
        other.destroy_node()
