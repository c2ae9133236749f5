"""`history` of a run that did not finish says so, as `report` does: a run stopped by SIGINT, SIGTERM or an
error closes its bag without its end-of-run record, and `history` printed its records as if the last were a
result. Here the bag is closed as such a run's is (InProcessBag.close without answers)."""
from __future__ import annotations

import pytest

pytest.importorskip("rclpy")


def _bag(tmp_path, answers: dict | None, config: dict | None = None, unsigned_answers: bool = False):
    from bev_mdo.api.runbag import InProcessBag

    bag = InProcessBag(tmp_path / "b", config or {"name": "t"}, "run1")
    for i, x in enumerate((3.0, 1.0, 1.5)):
        bag({"iteration": i, "design": {"x": x}, "objective": (x - 1.0) ** 2, "constraints": {}, "feasible": True,
             "max_violation": 0.0})
    if unsigned_answers:
        bag.signer = None
    bag.close(answers)  # without answers: as the run's closing does on a signal or an error
    return tmp_path / "b"


def test_history_of_an_interrupted_run_says_it_did_not_finish_at_its_last_iteration(tmp_path, capsys):
    from bev_mdo.cli import main

    bag = _bag(tmp_path, None)
    assert main(["history", str(bag), "--csv", "-"]) == 0
    out, err = capsys.readouterr()
    assert len(out.strip().splitlines()) == 1 + 3
    said = [line for line in err.splitlines() if "did not finish" in line]
    assert said == [f"{bag}: the run did not finish: the bag holds no end-of-run record (a signal, SIGINT or SIGTERM, "
                    "or an error stopped it); iteration 2 is its last recorded iterate, not a result"], err
    assert main(["history", str(bag), "--run-id", "another"]) == 1  # another run's records: not this bag's ending
    assert "did not finish" not in capsys.readouterr().err


def test_history_of_a_finished_run_says_nothing_of_its_ending(tmp_path, capsys):
    from bev_mdo.cli import main

    bag = _bag(tmp_path, {"feasible": True, "lines": [], "result_design": {"x": 1.0}})
    assert main(["history", str(bag), "--csv", "-"]) == 0
    assert "did not finish" not in capsys.readouterr().err


def test_history_of_a_run_whose_answers_are_left_out_does_not_call_it_unfinished(tmp_path, capsys):
    """A signed run's end-of-run record not signed with its key is left out: how the run ended is not known."""
    from bev_mdo.cli import main
    from bev_mdo.protocol.signing import new_key_file

    key = new_key_file(tmp_path / "keys")
    bag = _bag(tmp_path, {"feasible": True, "lines": [], "result_design": {"x": 1.0}},
               {"name": "t", "ros": {"sign_key_file": key}}, unsigned_answers=True)
    assert main(["history", str(bag), "--csv", "-"]) == 0
    assert "did not finish" not in capsys.readouterr().err


def test_report_of_a_run_stopped_before_its_first_record_does_not_promise_an_iterate(tmp_path):
    """A run stopped in start-up left a bag without records: report's first line said 'what follows is its last
    recorded iterate', then 'No iteration records in this bag.'"""
    from bev_mdo.api.runbag import InProcessBag
    from bev_mdo.bag.report import report

    InProcessBag(tmp_path / "b", {"name": "t"}, "run1").close(None)
    report(tmp_path / "b", tmp_path / "out")
    text = (tmp_path / "out" / "report.md").read_text()
    assert "the bag holds no end-of-run record (a signal, SIGINT or SIGTERM, or an error stopped it), and no " \
           "iteration record either" in " ".join(text.split()), text
    assert "last recorded iterate" not in text


def test_report_of_a_run_whose_answers_are_left_out_heads_its_iterate_as_not_known(tmp_path):
    """With its end-of-run record left out (forged or unsigned), report said "how the run ended is not known", then
    headed the iterate "Last recorded iterate (the run did not finish)"."""
    from bev_mdo.bag.report import report
    from bev_mdo.protocol.signing import new_key_file

    key = new_key_file(tmp_path / "keys")
    bag = _bag(tmp_path, {"feasible": True, "lines": [], "result_design": {"x": 1.0}},
               {"name": "t", "ros": {"sign_key_file": key}}, unsigned_answers=True)
    report(bag, tmp_path / "out", key_file=key)
    text = (tmp_path / "out" / "report.md").read_text()
    assert text.splitlines()[2].startswith("- how the run ended is not known"), text
    assert "## Last recorded iterate (how the run ended is not known)" in text and "did not finish" not in text


def test_report_of_a_bag_cut_before_its_records_does_not_say_the_run_finished(tmp_path):
    """A bag cut short before its first message, its run's answers.json beside it: report said "the run finished:
    the bag holds its end-of-run record (its result and the answers below)", then "No iteration records". What the
    bag shows is not known; the record beside it says the run finished."""
    from bev_mdo.bag.history import ANSWERS_FILE
    from bev_mdo.bag.report import report
    from bev_mdo.bag.writer import BagWriter

    bag = tmp_path / "ros"
    with BagWriter(bag, metadata={"config_yaml": "name: t\n", "run_id": "run1"}) as w:
        w.add_topic("/bev_mdo/iteration", "bev_mdo_msgs/msg/IterationRecord")
    (bag / ANSWERS_FILE).write_text('{"feasible": true, "lines": [], "result_design": {"x": 1.0}, "records": 3, '
                                    '"last_iteration": 2}\n')
    report(bag, tmp_path / "out")
    text = (tmp_path / "out" / "report.md").read_text()
    assert text.splitlines()[2] == ("- how the run ended is not known from the bag: **it holds none of the run's 3 "
                                    "iteration records**; its end-of-run record (answers.json beside the bag) says the "
                                    "run finished"), text
    assert "the run finished:" not in text and "No iteration records in this bag." in text
