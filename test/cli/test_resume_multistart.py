"""An interrupted multi-start (``--starts N``) resumes every start from its own last record. Its records
did not say which start made them, so resume went on from the bag's last record alone: one start of the
N, whichever wrote last, as a single-start run."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.cli import main
from test.cli.stopped_runs import interrupted_run

SELLAR = Path(__file__).resolve().parents[2] / "examples" / "sellar" / "sellar_mdf.yaml"


def _interrupted(bag: Path, starts: int, after: int) -> None:
    """An in-process multi-start of Sellar stopped after ``after`` records, as by a signal: no answers stored."""
    interrupted_run(SELLAR, bag, after, starts=starts, seed=3)


def _by_start(rows: list[dict]) -> dict[int, list[dict]]:
    out: dict[int, list[dict]] = {}
    for r in rows:
        out.setdefault(r["start"], []).append(r)
    return out


def test_each_start_resumes_from_its_own_last_record(tmp_path, capsys):
    from bev_mdo.bag.history import history, last_iterate

    old, new = tmp_path / "old", tmp_path / "new"
    _interrupted(old, starts=3, after=7)
    rows = history(old)
    assert len(rows) == 7 and {(r["starts"], r["seed"]) for r in rows} == {(3, 3)}
    old_by_start = _by_start(rows)
    assert sorted(old_by_start) == [1, 2, 3]  # every start wrote its start point first
    _, designs, _ = last_iterate(old)
    assert designs == [old_by_start[s][-1]["design"] for s in (1, 2, 3)]
    assert main(["resume", str(old), "--transport", "inprocess", "--output", str(new), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "the last record of each of its 3 starts" in out and "given start points" in out
    new_rows = history(new)
    assert {(r["starts"], r["seed"]) for r in new_rows} == {(3, None)}
    for s, recs in _by_start(new_rows).items():  # each start begins where it was stopped
        last = old_by_start[s][-1]
        assert recs[0]["design"] == last["design"] and recs[0]["objective"] == last["objective"]


def test_a_start_without_a_record_begins_at_its_point_of_the_sample_again(tmp_path, capsys):
    from bev_mdo.bag.history import history
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.multistart import start_points

    old, new = tmp_path / "old", tmp_path / "new"
    _interrupted(old, starts=3, after=1)  # only the first start's point was recorded
    assert [r["start"] for r in history(old)] == [1]
    assert main(["resume", str(old), "--transport", "inprocess", "--output", str(new), "--quiet"]) == 0
    assert "iterations 0, none, none" in capsys.readouterr().out
    sample = start_points(RunConfig.load(SELLAR).settings.optimisation_problem(), 3, seed=3)
    firsts = {s: recs[0]["design"] for s, recs in _by_start(history(new)).items()}
    assert firsts[2] == pytest.approx(sample[1], rel=0, abs=0) and firsts[3] == pytest.approx(sample[2], rel=0, abs=0)


def test_history_of_an_interrupted_multi_start_names_the_start_of_its_last_iterate(tmp_path, capsys):
    """history said 'iteration N is its last recorded iterate' as of a single run, while resume goes on from
    each start's own last record."""
    from bev_mdo.bag.history import history

    old = tmp_path / "old"
    _interrupted(old, starts=3, after=7)
    last = history(old)[-1]
    assert main(["history", str(old), "--csv", "-"]) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if "did not finish" in line]
    assert said == [f"{old}: the run did not finish: the bag holds no end-of-run record (a signal, SIGINT or SIGTERM, "
                    f"or an error stopped it); iteration {last['iteration']} is the last recorded iterate of its start "
                    f"{last['start']} of 3 (resume goes on from each start's own last record), not a result"], said
