"""Ctrl-C at the end of `optimize`: the last line says what is true whenever the signal comes, naming the bag.

Once the run has its bag, a signal before the result is stored ends with `bev-mdo: interrupted` and what the
bag holds; once the result is stored with it, with one line saying the bag is complete and whether the result
was printed. It once depended on where in the code the signal landed: a bare `bev-mdo: interrupted` in the
steps between the run and the answers (the baseline in process, the cycle check, over ROS the run's
summary), though the bag held every iteration; in process, one between the run's own steps and the answers' (the
result turned into its document) left the bag unclosed, no metadata.yaml, though the line said it held them;
and `... while the result was printed` before a line of it
was (a signal while rich was imported, or while it rendered the table). The signal is raised here, in process, from the step named.
"""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo import interrupts
from bev_mdo.bag.reader import open_bag
from bev_mdo.cli import _main, main

LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def _complete(bag) -> str:
    return f"the bag {bag} is complete (bev-mdo report {bag}; bev-mdo history {bag})"


def _result_printed(bag, records):
    """The table was written (a signal in the verdict below it)."""
    return [f"bev-mdo: interrupted while the result was printed; {_complete(bag)}"]


def _result_not_printed(bag, records):
    """Nothing of the result was written yet: it said `while the result was printed`."""
    return [f"bev-mdo: interrupted before the result was printed; {_complete(bag)}"]


def _bag_holds(bag, records):
    """The result not stored yet: what the bag holds (a bare `bev-mdo: interrupted` after the run's own step, and
    in process the bag was left unclosed: no metadata.yaml, read as truncated)."""
    return ["bev-mdo: interrupted", f"bev-mdo: bag {bag}: {records} iteration records, every finished iteration "
            f"(bev-mdo history {bag}; bev-mdo resume {bag} goes on from the last)"]


@pytest.mark.parametrize("module, step, last_lines", [("bev_mdo.cli.optimize", "_verdict", _result_printed),
                                                      ("bev_mdo.cli.optimize", "_table", _result_not_printed),
                                                      ("rich.table.Table", "__rich_console__", _result_not_printed),
                                                      ("bev_mdo.api.runbag", "answers", _bag_holds),
                                                      ("bev_mdo.sessions", "analyse_baseline", _bag_holds),
                                                      ("bev_mdo.mdo.driver.RunResult", "to_dict", _bag_holds)])
def test_a_signal_at_the_end_of_a_run_closes_the_bag_and_names_it(tmp_path, monkeypatch, capsys, module, step,
                                                                  last_lines):
    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(f"{module}.{step}", ctrl_c)
    bag = tmp_path / "bag"
    assert main(["optimize", LEAF, "--transport", "inprocess", "--bag", str(bag), "--quiet"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    expected = last_lines(bag, open_bag(bag).message_count)
    assert err[-len(expected):] == expected, err
    assert (bag / "metadata.yaml").is_file() and open_bag(bag).message_count > 0 and not open_bag(bag).truncated


def test_a_signal_just_before_the_process_marks_its_work_done_is_caught(tmp_path, monkeypatch, capsys):
    """`_main` marked the work done (interrupts.work_done: a signal then ends the process at once, with its line)
    after `_run` had returned: a signal taken in between, at work_done's first line, was raised out of main
    (a traceback). It is now taken where the output is flushed, and said; the status is a signal's."""
    calls = []

    def work_done(status):
        calls.append(status)
        if len(calls) == 1:  # the signal, taken as work_done is entered (Python checks for signals at a call)
            raise KeyboardInterrupt

    monkeypatch.setattr(interrupts, "work_done", work_done)
    bag = tmp_path / "bag"
    previous = interrupts.install()
    try:
        status = _main(["optimize", LEAF, "--transport", "inprocess", "--bag", str(bag), "--quiet"], process=True)
    except KeyboardInterrupt:  # (not raised on to pytest, which would stop the session)
        pytest.fail("the signal was raised out of _main")
    finally:
        interrupts.restore(previous)
    out, err = capsys.readouterr()
    assert status == 130 and calls == [0, 130], calls
    assert "verdict: optimum" in out
    assert err.strip().splitlines()[-1] == f"bev-mdo: interrupted while the result was printed; {_complete(bag)}"


@pytest.mark.parametrize("printing, done, line", [
    (False, [], ["bev-mdo: interrupted"]),
    (False, ["the bag B is complete"], ["bev-mdo: interrupted before the result was printed; the bag B is complete"]),
    (True, ["the bag B is complete"], ["bev-mdo: interrupted while the result was printed; the bag B is complete"])])
def test_the_line_of_a_signal_follows_what_was_stored_and_printed(monkeypatch, printing, done, line):
    monkeypatch.setattr(interrupts, "_printing", printing)
    monkeypatch.setattr(interrupts, "_done_notes", done)
    monkeypatch.setattr(interrupts, "_bag_note", None)
    assert interrupts.interrupted_lines(KeyboardInterrupt()) == line
    monkeypatch.setattr(interrupts, "_bag_note", lambda: "bag B: 3 iteration records")
    assert interrupts.interrupted_lines(interrupts.Terminated())[-1] == (
        "bev-mdo: bag B: 3 iteration records" if not done else line[0].replace("interrupted", "terminated (SIGTERM)"))
