"""A run's recorder that closed its bag and was then killed in its ROS teardown (at nice 10 on a crowded
host, SIGTERM after Launcher.stop's wait) did not fail the run; one killed before it closed the bag did
(sessions.recorder_failure), without processes."""
from __future__ import annotations

from pathlib import Path

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


def _iteration_bag(tmp_path, records: int):
    """A bag its recorder closed holding `records` iteration records (their bytes are not read here)."""
    from bev_mdo.bag.writer import BagWriter

    bag_dir = tmp_path / "run"
    writer = BagWriter(bag_dir)
    writer.add_topic("/bev_mdo/iteration", "bev_mdo_msgs/msg/IterationRecord")
    for i in range(records):
        writer.write("/bev_mdo/iteration", b"\x00\x01\x00\x00", i + 1, i + 1)
    writer.close()
    return bag_dir


@pytest.mark.parametrize("status", [0, 143, -15])
def test_a_recorder_that_ended_unseen_with_records_missing_is_one_warning(tmp_path, status):
    """SIGTERMed mid-run, a recorder still draining and closing its bag (or in its teardown) when the run ended was
    never seen to end during the run: it exited 0 to Launcher.stop's SIGINT (or was killed closed), and the run
    exited 0 without a word, its bag 462 records short. What the bag holds against what the run published decides."""
    bag = _iteration_bag(tmp_path, 390)
    note = sessions.recorder_failure(_launcher(status, during=False), bag, {"/bev_mdo/iteration": 852})
    assert note == (f"the recorder stopped recording before the run ended (exit status {status}); the bag holds 390 of "
                    "the 852 iteration records the run published (390 messages, closed by the recorder)")
    assert not list(bag.glob("*.bak*"))


def test_a_recorder_that_recorded_all_the_run_published_is_no_failure(tmp_path):
    bag = _iteration_bag(tmp_path, 31)
    assert sessions.recorder_failure(_launcher(0, during=False), bag, {"/bev_mdo/iteration": 31}) is None


def test_a_recorder_seen_to_stop_during_the_run_says_what_its_bag_lacks(tmp_path):
    bag = _iteration_bag(tmp_path, 265)
    note = sessions.recorder_failure(_launcher(0, during=True), bag, {"/bev_mdo/iteration": 852})
    assert note == ("the recorder stopped (exit status 0) during the run; the bag holds only what it recorded before: "
                    "265 of the 852 iteration records the run published (265 messages, closed by the recorder)")


def test_the_session_counts_the_records_its_run_published(tmp_path, monkeypatch):
    """OptimizeRosSession gives recorder_failure the count of records its coordinator published (the callback it
    passes on), so the run's summary warns when the bag lacks any."""
    from bev_mdo.ros import coordinator_node

    seen = []

    def run(config, *, on_iteration, **kw):
        for i in range(5):
            on_iteration({"iteration": i})
        return type("R", (), {"summary": lambda self: {}})(), {"t_optimised": 0.0, "dropped": {}, "retried": 0}

    monkeypatch.setattr(coordinator_node, "run", run)
    monkeypatch.setattr("bev_mdo.sessions.teardown", lambda close: None)
    monkeypatch.setattr("rclpy.init", lambda **kw: None)
    from bev_mdo.config import load_config

    sellar = Path(__file__).resolve().parents[1] / "examples" / "sellar" / "sellar_mdf.yaml"
    session = sessions.OptimizeRosSession(load_config(sellar), {"domain_id": 198}, tmp_path / "b", "r")
    session.launcher, session.recorder = _launcher(0, during=False), 1
    monkeypatch.setattr(sessions, "recorder_failure", lambda la, bag, sent: seen.append(sent))
    session.run(on_iteration=lambda rec: None)
    session.t_end = 1.0
    session.summary()
    assert seen == [{"/bev_mdo/iteration": 5}]
