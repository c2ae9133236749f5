"""A run's recorder that closed its bag and was then killed in its ROS teardown (at nice 10 on a crowded
host, SIGTERM after Launcher.stop's wait) did not fail the run; one killed before it closed the bag did
(sessions.recorder_failure), without processes."""
from __future__ import annotations

from bev_mdo import sessions
from bev_mdo.ros.launch import Launcher, NodeProcess


def _bag(tmp_path, closed: bool):
    from rclpy.serialization import serialize_message
    from std_msgs.msg import String

    from bev_mdo.bag.writer import BagWriter

    bag_dir = tmp_path / "run"
    writer = BagWriter(bag_dir)
    writer.add_topic("/chatter", "std_msgs/msg/String")
    for i in range(3):
        writer.write("/chatter", serialize_message(String(data=f"m{i}")), i + 1, i + 1)
    writer.flush()
    if closed:
        writer.close()
    return bag_dir


def _launcher(status: int) -> Launcher:
    la = Launcher({})
    la.nodes = [NodeProcess("recorder", [], restart=False, died=status)]
    return la


def test_a_recorder_killed_after_it_closed_its_bag_is_no_failure(tmp_path):
    bag = _bag(tmp_path, closed=True)
    assert sessions.recorder_failure(_launcher(-15), bag) is None


def test_a_recorder_killed_before_it_closed_its_bag_is_one_warning_and_the_bag_is_repaired(tmp_path):
    from bev_mdo.bag.reader import open_bag

    bag = _bag(tmp_path, closed=False)
    note = sessions.recorder_failure(_launcher(-9), bag)
    assert note.startswith("the recorder died (exit status -9) during the run") and "metadata rebuilt" in note
    repaired = open_bag(bag, strict=False)
    assert not repaired.truncated and repaired.message_count == 3
