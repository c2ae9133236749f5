"""A run knows its recorder by its declaration (recorder_node.OwnRecorder), never by a count of readers;
the recorder records only its own run. No DDS here: declarations and the graph are made up."""
from __future__ import annotations

import json
from types import SimpleNamespace

import pytest
from rclpy.serialization import serialize_message

from bev_mdo.binding import config_binding
from bev_mdo.protocol.messages import run_of
from bev_mdo.protocol.signing import Signer
from bev_mdo.ros.recorder_node import OwnRecorder

KEY, OTHER_KEY = b"k" * 32, b"o" * 32
BINDING = config_binding("problem: {a: 1}\n")


class FakeNode:
    """The graph a coordinator node sees: readers per topic; its own name."""

    def __init__(self, readers):
        self.readers = readers
        self.handler = None

    def create_subscription(self, _type, _topic, handler, _qos):
        self.handler = handler

    def get_subscriptions_info_by_topic(self, topic):  # a reader "name:type" has that type, else the run's
        return [SimpleNamespace(node_namespace="/", node_name=n.split(":")[0],
                                topic_type=n.split(":")[1] if ":" in n else "bev_mdo_msgs/msg/IterationRecord")
                for n in self.readers.get(topic, [])]

    def get_fully_qualified_name(self):
        return "/coordinator_r1"


def _declare(node, signer=None, **fields):
    body = {"run_id": "r1", "binding": BINDING, "recorder": "/recorder_r1", "bag": "b",
            "matched": {"/bev_mdo/iteration": 1}, "publishers": {"/bev_mdo/iteration": ["/coordinator_r1"],
                                                                  "/bev_mdo/result": ["/energy_node_r1"]}}
    body.update(fields)
    text = json.dumps(body, sort_keys=True)
    node.handler(SimpleNamespace(data=json.dumps(
        {"declaration": text, "signature": signer.sign_declaration(text) if signer else ""})))


def test_only_this_runs_signed_declaration_with_its_binding_is_taken():
    node = FakeNode({})
    own = OwnRecorder(node, "r1", Signer(KEY), BINDING)
    _declare(node, Signer(KEY), run_id="r2")                 # another run's recorder
    _declare(node)                                            # unsigned
    _declare(node, Signer(OTHER_KEY))                         # signed with another key
    _declare(node, Signer(KEY), binding="0123456789abcdef")  # another configuration in the bag
    node.handler(SimpleNamespace(data="not json"))
    assert own.declaration is None
    assert dict(own.dropped) == {"recorder_other_run": 1, "recorder_unsigned": 1, "recorder_forged": 1,
                                 "recorder_other_binding": 1, "recorder_malformed": 1}
    _declare(node, Signer(KEY))
    assert own.name == "/recorder_r1"


def test_a_sub_run_takes_its_parent_runs_recorder():
    node = FakeNode({})
    own = OwnRecorder(node, "r1-baseline", None, None)
    _declare(node)
    assert own.name == "/recorder_r1"


def test_readers_count_only_when_the_declared_recorder_is_among_them_and_matched_us():
    topic = "/bev_mdo/iteration"
    node = FakeNode({topic: ["stranger", "recorder_other_run"]})
    own = OwnRecorder(node, "r1", None, None)
    from bev_mdo_msgs.msg import IterationRecord

    pub = SimpleNamespace(get_subscription_count=lambda: 2, msg_type=IterationRecord)
    assert not own.records(topic, pub=pub)  # no declaration yet: two readers say nothing
    _declare(node)
    assert not own.records(topic, pub=pub)  # declared, but not reading this topic in our graph
    node.readers[topic].append("recorder_r1")
    assert not own.records(topic, pub=pub)  # our writer matched 2 of the 3 readers
    pub.get_subscription_count = lambda: 3
    assert own.records(topic, pub=pub)
    node.readers[topic].append("squatter:std_msgs/msg/String")
    assert own.records(topic, pub=pub)  # a reader of another type can never match: it is not waited for
    _declare(node, publishers={topic: []})  # the recorder has not matched our publisher yet
    assert not own.records(topic, pub=pub)


def test_result_topics_need_every_one_of_the_runs_publishers_matched():
    node = FakeNode({})
    own = OwnRecorder(node, "r1", None, None)
    _declare(node)
    assert own.records("/bev_mdo/result", publishers=["energy_node_r1"])
    assert not own.records("/bev_mdo/result", publishers=["energy_node_r1", "range_node_r1"])


@pytest.mark.parametrize("frame_id", ["", "a", "ab", "abc", "fp:energy=0123456789abcdef,range=fedcba9876543210"])
def test_the_run_of_a_message_is_read_from_its_bytes(frame_id):
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult, IterationRecord

    for cls in (EvaluationRequest, EvaluationResult, IterationRecord):
        msg = cls()
        msg.header.frame_id, msg.run_id = frame_id, "0123456789abcdef-baseline"
        assert run_of(serialize_message(msg)) == msg.run_id
    assert run_of(b"\x00\x01\x00\x00") is None
