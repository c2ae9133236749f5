"""What a bag tells after a run whose records it does not all hold, and after a multi-start.

A recorder SIGKILLed during a run (over ROS) leaves a bag whose iteration records stop there, while the run
goes on to its result and stores its end-of-run record (answers.json) beside it. ``report`` then called the
bag's last record the "Final iterate" of a run that "finished", ``history`` showed the short table with no
word, and ``resume`` went on from that record, not from the result. Here the same bag is made in process:
the bag's writer stops taking records after the third (as the dead recorder did), the run goes on and stores
its answers. A multi-start's report gave the last start's evaluation count as the run's, and the resume of a
multi-start of many starts listed every start's iteration on one line.
"""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

pytest.importorskip("rclpy")

ROOT = Path(__file__).resolve().parents[2]
SELLAR = ROOT / "examples" / "sellar" / "sellar_mdf.yaml"


def _optimize(bag: Path, *flags: str) -> dict:
    from bev_mdo.cli import main

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(["optimize", str(SELLAR), "--transport", "inprocess", "--bag", str(bag), "--json", "--quiet", *flags])
    return json.loads(buf.getvalue())


def _bag_stops_after(monkeypatch, kept: int) -> None:
    """The in-process bag writes its first ``kept`` records only; the run goes on and stores its answers."""
    from bev_mdo.api.runbag import InProcessBag

    write = InProcessBag.__call__

    def first_only(self, rec):
        if self.seq < kept:
            write(self, rec)

    monkeypatch.setattr(InProcessBag, "__call__", first_only)


def _report(bag: Path, out: Path) -> str:
    from bev_mdo.bag.report import report

    report(bag, out)
    return (out / "report.md").read_text()


def test_a_bag_whose_records_stop_early_names_the_runs_result(tmp_path, monkeypatch):
    from bev_mdo.bag.history import check_note, history, last_iterate

    _bag_stops_after(monkeypatch, 3)
    bag = tmp_path / "bag"
    doc = _optimize(bag)
    end = doc["iterations"]
    assert end > 2 and doc["result_iteration"] == end
    checks: dict = {}
    assert len(history(bag, checks=checks)) == 3
    # what is known: the records stop before the run's end; why (a recorder stopped, records removed) is not
    assert (f"the bag's iteration records stop at iteration 2 of the run's {end} ({end - 2} missing at the end: its "
            "recorder stopped before the run ended, or records were removed from the bag)") in check_note(checks)
    md = _report(bag, tmp_path / "r")
    assert md.splitlines()[2].startswith("- the run finished, but **the bag's iteration records stop at iteration 2 "
                                         f"of the run's {end}")
    assert "- 3 records (iterations 0-2)" in md and "## Final iterate" not in md
    assert f"## The run's result (iteration {end}, from its end-of-run record)" in md
    assert f"Best feasible objective {doc['objective']:.6g} at iteration {end} (the run's result)." in md
    checks = {}
    _, design, k = last_iterate(bag, checks=checks)
    assert design == doc["design"] and k == end
    assert checks["result"].startswith(f"the run's result (iteration {end}, from its end-of-run record")


def test_answers_that_do_not_count_the_records_still_name_the_result(tmp_path, monkeypatch):
    """An end-of-run record stored before it counted the records (the trial's bag): the result it names is
    on no record of the bag, so the records stopped before it; its objective is the design analysed again."""
    from bev_mdo.api.runbag import InProcessBag
    from bev_mdo.bag.history import last_iterate

    _bag_stops_after(monkeypatch, 3)
    close = InProcessBag.close
    counted = ("records", "last_iteration", "result_iteration", "result_objective", "result_max_violation",
               "result_feasible", "mda_evaluations")
    monkeypatch.setattr(InProcessBag, "close", lambda self, answers=None: close(
        self, None if answers is None else {k: v for k, v in answers.items() if k not in counted}))
    bag = tmp_path / "bag"
    doc = _optimize(bag)
    md = _report(bag, tmp_path / "r")
    assert "the bag's iteration records stop at iteration 2, before the run's result" in md.splitlines()[2]
    assert "## The run's result (iteration not recorded, from its end-of-run record)" in md
    objective = next(line for line in md.splitlines() if line.startswith(f"| {doc['objective_name']} |"))
    assert float(objective.split("|")[3]) == pytest.approx(doc["objective"], rel=1e-5)  # printed to 6 digits
    assert last_iterate(bag)[1] == doc["design"]


def test_a_multi_start_report_gives_the_runs_evaluation_count(tmp_path):
    doc = _optimize(tmp_path / "bag", "--starts", "3", "--seed", "2")
    md = _report(tmp_path / "bag", tmp_path / "r")
    assert f", {doc['mda_evaluations']} multidisciplinary evaluations (the run's total)" in md


def test_an_interrupted_multi_start_counts_every_starts_evaluations(tmp_path):
    from bev_mdo.bag.history import history
    from test.cli.stopped_runs import interrupted_run

    interrupted_run(SELLAR, tmp_path / "bag", 9, starts=3, seed=3)
    last: dict = {}
    for r in history(tmp_path / "bag"):
        last[r["start"]] = r["mda_evaluations"]
    assert len(last) == 3
    md = _report(tmp_path / "bag", tmp_path / "r")
    assert f"{sum(last.values())} multidisciplinary evaluations (to the last record of each of its 3 starts)" in md


def test_the_resume_of_many_starts_says_it_in_counts(tmp_path):
    """12 starts stopped after 5 records: a count and a few of each kind, not twelve numbers on the line."""
    from bev_mdo.bag.history import last_iterate
    from test.cli.stopped_runs import interrupted_run

    interrupted_run(SELLAR, tmp_path / "bag", 5, starts=12, seed=3)
    checks: dict = {}
    designs = last_iterate(tmp_path / "bag", checks=checks)[1]
    assert sum(d is not None for d in designs) == 5
    with_record = [i + 1 for i, d in enumerate(designs) if d is not None]
    none = [i + 1 for i, d in enumerate(designs) if d is None]
    said = checks["starts"]
    assert said.startswith(f"the last record of each of its 12 starts: 5 with a record (start {with_record[0]} at "
                           "iteration ")
    assert said.endswith(f"and 2 more), 7 with none (starts {none[0]}, {none[1]}, {none[2]} and 4 more)")
    assert said.count("start ") == 3  # three examples of the five


def test_replay_of_a_bag_whose_records_stop_early_says_so(tmp_path, monkeypatch, capsys):
    """`replay` of a bag whose last records were removed published 29 of its run's 31 iterations without a word;
    it says the bag lacks records, in history's line, before it publishes anything (its check of the bag)."""
    from argparse import Namespace

    from bev_mdo.cli.replay import verify

    _bag_stops_after(monkeypatch, 3)
    bag = tmp_path / "bag"
    end = _optimize(bag)["iterations"]
    capsys.readouterr()
    verify(Namespace(bag=str(bag), key_file=None, no_verify=False))
    said = [line for line in capsys.readouterr().err.splitlines() if "stop at iteration" in line]
    assert len(said) == 1 and said[0].startswith(f"{bag}: the bag's iteration records stop at iteration 2 of the run's "
                                                 f"{end} ({end - 2} missing at the end"), said
