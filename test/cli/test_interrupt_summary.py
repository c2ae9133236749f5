"""Ctrl-C while `optimize` prints its end-of-run summary: the bag is complete and the answers stored, but the
last line was a bare `bev-mdo: interrupted`, with no bag path and no word that it is complete (the line a
signal a moment later gives, after the output, is `... after the result was written; the bag B is
complete`). Which one a user got depended on when the signal came. The signal is raised here, in process,
from the printing of the result table."""
from __future__ import annotations

from pathlib import Path

from bev_mdo.bag.reader import open_bag
from bev_mdo.cli import main

LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def test_a_signal_while_the_result_is_printed_names_the_complete_bag(tmp_path, monkeypatch, capsys):
    from bev_mdo.cli import optimize

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(optimize, "_table", ctrl_c)
    bag = tmp_path / "bag"
    assert main(["optimize", LEAF, "--transport", "inprocess", "--bag", str(bag), "--quiet"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == f"bev-mdo: interrupted while the result was printed; the bag {bag} is complete", err
    assert (bag / "metadata.yaml").is_file() and open_bag(bag).message_count > 0 and not open_bag(bag).truncated


def test_a_signal_while_the_answers_are_made_closes_the_bag_and_names_it(tmp_path, monkeypatch, capsys):
    """A moment earlier, while the end-of-run answers were computed, an in-process bag was left unclosed
    (no metadata.yaml, read as truncated) and the line was a bare `bev-mdo: interrupted`."""
    from bev_mdo.api import runbag

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(runbag, "answers", ctrl_c)
    bag = tmp_path / "bag"
    assert main(["optimize", LEAF, "--transport", "inprocess", "--bag", str(bag), "--quiet"]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    records = open_bag(bag).message_count
    assert err[-2:] == ["bev-mdo: interrupted", f"bev-mdo: bag {bag}: {records} iteration records, every finished "
                        f"iteration (bev-mdo history {bag}; bev-mdo resume {bag} goes on from the last)"], err
    assert (bag / "metadata.yaml").is_file() and not open_bag(bag).truncated
