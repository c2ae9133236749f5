"""The end-of-run answers stored with a signed run's bag are signed with its key. They name the run's
result, which ``resume`` goes on from and ``report`` describes; stored as plain metadata, answers
edited after the run (another recorded point named as the result, other active constraints) were taken
on the bag's word while every record beside them was verified."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.protocol.signing import Signer, new_key_file, read_key

pytest.importorskip("rclpy")


def _record(i: int, x: float) -> dict:
    return {"iteration": i, "design": {"x": x}, "objective": (x - 1.0) ** 2, "constraints": {}, "feasible": True,
            "max_violation": 0.0}


def _bag(tmp_path, name: str, answers_signer: str = "own"):
    """A signed in-process run's bag of 3 records whose answers name record 1 as the result, their
    signature made with the run's key ("own"), none ("none") or another key ("other")."""
    from bev_mdo.api.runbag import InProcessBag

    key = new_key_file(tmp_path / "keys" / name)
    bag = InProcessBag(tmp_path / name, {"name": "t", "ros": {"sign_key_file": key}}, "run1")
    for i, x in enumerate((3.0, 1.0, 1.5)):
        bag(_record(i, x))
    if answers_signer == "none":
        bag.signer = None
    elif answers_signer == "other":
        bag.signer = Signer(read_key(new_key_file(tmp_path / "keys" / f"{name}_other")))
    bag.close({"feasible": True, "lines": ["active: none"], "result_design": {"x": 1.0}})
    return tmp_path / name, key


def test_a_signed_runs_answers_verify_and_name_its_result(tmp_path):
    from bev_mdo.bag.history import last_iterate, read_answers
    from bev_mdo.bag.reader import open_bag

    bag, key = _bag(tmp_path, "own")
    assert read_answers(open_bag(bag), Signer(read_key(key)))["result_design"] == {"x": 1.0}
    checks: dict = {}
    _, design, k = last_iterate(bag, checks=checks)
    assert (design, k) == ({"x": 1.0}, 1) and "answers" not in checks


@pytest.mark.parametrize("how, why", [("none", "unsigned"), ("other", "forged")])
def test_answers_not_signed_with_the_runs_key_are_left_out(tmp_path, how, why):
    from bev_mdo.bag.history import check_note, last_iterate, read_answers
    from bev_mdo.bag.reader import open_bag

    bag, key = _bag(tmp_path, how, answers_signer=how)
    checks: dict = {}
    assert read_answers(open_bag(bag), Signer(read_key(key)), checks) is None
    assert f"end-of-run answers are {why}" in checks["answers"]
    assert read_answers(open_bag(bag))["result_design"] == {"x": 1.0}  # unverified reading (no key): as stored
    checks = {}
    _, design, k = last_iterate(bag, checks=checks)
    assert (design, k) == ({"x": 1.5}, 2)  # the last verified record, not the point the answers name
    assert f"end-of-run answers are {why}" in check_note(checks)
    from bev_mdo.bag.report import report

    checks = {}
    report(bag, tmp_path / f"report_{how}", checks=checks)  # report leaves them out the same way
    assert f"end-of-run answers are {why}" in checks["answers"]


def test_answers_json_beside_a_ros_bag_is_signed_with_the_run_key(tmp_path, monkeypatch):
    """Over ROS the answers are a file beside the recorder's bag (answers.json), its signature in answers.json.sig,
    made with the run's key where the readers find it (bag.signing.run_key_path)."""
    from bev_mdo.api import runbag
    from bev_mdo.bag.history import ANSWERS_FILE, read_answers
    from bev_mdo.bag.signing import run_key_path

    bag, key = _bag(tmp_path, "ros", answers_signer="none")
    ans = {"feasible": True, "lines": ["active: none"]}
    monkeypatch.setattr(runbag, "answers", lambda config, result: ans)
    meta = bag / ANSWERS_FILE
    runbag.finish({}, {"design": {"x": 1.0}}, {"bag": str(bag)})
    assert run_key_path(bag).resolve() == Path(key).resolve()
    signer = Signer(read_key(key))
    bag_obj = _without_metadata_answers(bag)
    assert read_answers(bag_obj, signer) == {**ans, "result_design": {"x": 1.0}}
    meta.write_text(meta.read_text().replace('"x": 1.0', '"x": 1.5'))  # another recorded point named as the result
    checks: dict = {}
    assert read_answers(bag_obj, signer, checks) is None and "forged" in checks["answers"]


def _without_metadata_answers(bag):
    """The bag as a reader sees it, with the in-process answers record set aside (a ROS bag has none)."""
    from bev_mdo.bag.history import ANSWERS_METADATA
    from bev_mdo.bag.reader import open_bag

    opened = open_bag(bag)
    opened.metadata.pop(ANSWERS_METADATA, None)
    return opened



@pytest.mark.parametrize("where", ["metadata", "answers.json"])
def test_history_says_how_the_run_ended_is_not_known_when_its_answers_are_forged(tmp_path, capsys, where):
    """End-of-run answers not signed with the run's key (in the bag's metadata, or answers.json beside a recorder's
    bag): report said how the run ended is not known, history said nothing."""
    from bev_mdo.bag.history import ANSWERS_FILE
    from bev_mdo.bag.writer import BagWriter
    from bev_mdo.cli import main

    bag, key = _bag(tmp_path, "forged", answers_signer="other")
    if where == "answers.json":  # the same records in a bag of their own, the forged answers beside it
        from bev_mdo.bag.reader import open_bag

        old = open_bag(bag)
        ros = tmp_path / "ros"
        with BagWriter(ros, metadata={"config_yaml": old.stored_config.text, "run_id": "run1"}) as w:
            w.add_topic("/bev_mdo/iteration", "bev_mdo_msgs/msg/IterationRecord")
            for m in old.messages():
                w.write(m.topic, m.data, m.log_time_ns)
        text = old.metadata["bev_mdo_answers"]["answers_json"]
        (ros / ANSWERS_FILE).write_text(text)
        (ros / (ANSWERS_FILE + ".sig")).write_text(old.metadata["bev_mdo_answers"]["answers_signature"])
        bag = ros
    assert main(["history", str(bag), "--csv", "-", "--key-file", key]) == 0
    err = capsys.readouterr().err
    assert "how the run ended is not known: its end-of-run record is left out (not signed with its key)" in err, err
