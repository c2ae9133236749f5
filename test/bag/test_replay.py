"""Replay a bag into a subscriber in this process and compare decoded values per topic."""
from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

from bev_mdo.testing import ros_env

from .conftest import ROOT, write_synthetic

pytestmark = [pytest.mark.ros, pytest.mark.slow]
DOMAIN = 44


@pytest.fixture(scope="module")
def node():
    import rclpy
    os.environ["ROS_DOMAIN_ID"] = str(DOMAIN)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    context = rclpy.context.Context()
    rclpy.init(context=context, domain_id=DOMAIN)
    from rclpy.node import Node

    from rclpy.executors import SingleThreadedExecutor

    node = Node("replay_test_subscriber", context=context)
    node.executor_for_test = SingleThreadedExecutor(context=context)
    node.executor_for_test.add_node(node)
    yield node
    node.executor_for_test.shutdown()
    node.destroy_node()
    rclpy.shutdown(context=context)


def _subscribe(node, topics_types, received):
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import deserialize_message

    from bev_mdo.ros.recorder_node import message_class

    qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=5000)
    subs = []
    for topic, type_name in topics_types.items():
        cls = message_class(type_name)
        subs.append(node.create_subscription(
            cls, topic, lambda data, t=topic, c=cls: received.setdefault(t, []).append(
                deserialize_message(data, c)), qos, raw=True))
    return subs


def _replay(bag, *args) -> subprocess.Popen:
    cmd = [sys.executable, "-c", "import sys; from bev_mdo.cli import main; sys.exit(main())",
           "replay", str(bag), "--wait-subscribers", "1", *args]
    return subprocess.Popen(cmd, env=ros_env(DOMAIN), cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _collect(node, proc, received, expected_count, timeout_s=60.0):
    deadline = time.monotonic() + timeout_s
    while sum(map(len, received.values())) < expected_count and time.monotonic() < deadline:
        node.executor_for_test.spin_once(timeout_sec=0.05)
    out, err = proc.communicate(timeout=60)
    return proc.returncode, out, err


def _per_topic(msgs):
    from rclpy.serialization import deserialize_message, serialize_message

    out = {}
    for topic, _ty, m in msgs:
        out.setdefault(topic, []).append(deserialize_message(serialize_message(m), type(m)))
    return out


@pytest.mark.parametrize("speed", [["--as-fast-as-possible"], ["--rate", "2.0"]])
def test_replay_into_subscriber(node, tmp_path, speed):
    bag = tmp_path / "run"
    msgs = write_synthetic(bag, n_iterations=30)
    received: dict[str, list] = {}
    subs = _subscribe(node, {t: ty for t, ty, _m in msgs}, received)
    try:
        code, out, err = _collect(node, _replay(bag, *speed), received, len(msgs))
    finally:
        for s in subs:
            node.destroy_subscription(s)
    assert code == 0, err
    assert f"replayed {len(msgs)} messages" in out
    assert received == _per_topic(msgs)   # generated classes compare field by field


def test_truncated_bag_replays_complete_part(node, tmp_path):
    from bev_mdo.bag.reader import open_bag

    bag = tmp_path / "run"
    msgs = write_synthetic(bag, n_iterations=40, chunk_size_bytes=1500)
    mcap = bag / "run_0.mcap"
    data = mcap.read_bytes()
    mcap.write_bytes(data[: len(data) // 2])
    (bag / "metadata.yaml").unlink()
    n = open_bag(bag).message_count
    assert 0 < n < len(msgs)
    received: dict[str, list] = {}
    subs = _subscribe(node, {t: ty for t, ty, _m in msgs}, received)
    try:
        code, out, err = _collect(node, _replay(bag, "--as-fast-as-possible"), received, n)
    finally:
        for s in subs:
            node.destroy_subscription(s)
    assert code == 0, err
    assert "truncated" in err and f"replayed {n} messages" in out
    assert received == _per_topic(msgs[:n])


def test_replay_bad_input_exit_2(tmp_path):
    bad = tmp_path / "bad.mcap"
    bad.write_text("not a bag\n")
    code, out, err = _collect_only(_replay(bad))
    assert code == 2 and err.strip().count("\n") == 0 and "not an MCAP file" in err and str(bad) in err


def _collect_only(proc):
    out, err = proc.communicate(timeout=60)
    return proc.returncode, out, err
