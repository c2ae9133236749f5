"""A run's recorder that closed its bag and was then killed in its ROS teardown (at nice 10 on a crowded
host, SIGTERM after Launcher.stop's wait) did not fail the run; one killed before it closed the bag did
(sessions.recorder_failure), without processes."""
from __future__ import annotations

import pytest

from bev_mdo import sessions
from bev_mdo.launcher import Launcher, NodeProcess


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


def _launcher(status: int, during: bool) -> Launcher:
    """A launcher whose recorder ended with `status`: during the run (seen by its supervisor), or when the run's
    end stopped it (the supervisor is stopped first: only the process's return code tells)."""
    la = Launcher({})
    node = NodeProcess("recorder", [], restart=False, died=status if during else None)
    node.proc = type("Ended", (), {"returncode": status})()
    la.nodes = [node]
    return la


def test_a_recorder_killed_after_it_closed_its_bag_is_no_failure(tmp_path):
    bag = _bag(tmp_path, closed=True)
    assert sessions.recorder_failure(_launcher(-15, during=False), bag) is None


def test_a_recorder_killed_before_it_closed_its_bag_is_one_warning_and_the_bag_is_repaired(tmp_path):
    from bev_mdo.bag.reader import open_bag

    bag = _bag(tmp_path, closed=False)
    note = sessions.recorder_failure(_launcher(-9, during=True), bag)
    assert note.startswith("the recorder died (exit status -9) during the run") and "metadata rebuilt" in note
    repaired = open_bag(bag, strict=False)
    assert not repaired.truncated and repaired.message_count == 3


@pytest.mark.parametrize("status", [143, 130, 0])
def test_a_recorder_that_ended_cleanly_during_the_run_is_one_warning(tmp_path, status):
    """SIGTERMed mid-run, a recorder closes its bag and exits 0 (130 or 143 if stopped while it starts): the bag is whole, but holds
    nothing recorded after that, so the run is told (status 3), not silently complete; the bag is left as the
    recorder closed it."""
    bag = _bag(tmp_path, closed=True)
    note = sessions.recorder_failure(_launcher(status, during=True), bag)
    assert note.startswith(f"the recorder stopped (exit status {status}) during the run") and "closed by the recorder" in note
    assert not list(bag.glob("*.bak*"))


@pytest.mark.parametrize("status", [130, 143, 0])
def test_a_recorder_that_exited_as_told_to_stop_is_no_failure(tmp_path, status):
    """Launcher.stop's SIGINT (then SIGTERM): the recorder closes its bag and exits 0 (130 or 143 if it was
    still starting)."""
    assert sessions.recorder_failure(_launcher(status, during=False), _bag(tmp_path, closed=True)) is None
