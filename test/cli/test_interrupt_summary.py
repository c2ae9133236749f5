"""Ctrl-C at the end of `optimize`: the bag is complete and the answers stored, but the last line was a bare
`bev-mdo: interrupted`, with no bag path and no word that it is complete (the line a signal a moment later
gives, after the output, is `... after the result was written; the bag B is complete`). Which one a user got
depended on when the signal came. The signal is raised here, in process, from the step named."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.bag.reader import open_bag
from bev_mdo.cli import main

LEAF = str(Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml")


def _result_printed(bag, records):
    return [f"bev-mdo: interrupted while the result was printed; the bag {bag} is complete"]


def _answers_made(bag, records):
    """A moment earlier, while the end-of-run answers were computed, an in-process bag was left unclosed
    (no metadata.yaml, read as truncated) and the line was a bare `bev-mdo: interrupted`."""
    return ["bev-mdo: interrupted", f"bev-mdo: bag {bag}: {records} iteration records, every finished iteration "
            f"(bev-mdo history {bag}; bev-mdo resume {bag} goes on from the last)"]


@pytest.mark.parametrize("module, step, last_lines", [("bev_mdo.cli.optimize", "_table", _result_printed),
                                                      ("bev_mdo.api.runbag", "answers", _answers_made)])
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
