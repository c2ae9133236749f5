"""An IDF run's records hold its couplings (the optimiser's variables, as IterationRecord.msg says), and a
start given to IDF begins with couplings consistent there. The records held the design variables only,
and a given start kept the couplings computed at the config's initial design: a resumed IDF run began
infeasible at iteration 0 (Sellar: y1, y2 of z = (5, 2), x = 1 at another design) and took 4 iterations
where MDF took 1."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.cli import main
from test.cli.stopped_runs import interrupted_run

SELLAR_IDF = Path(__file__).resolve().parents[2] / "examples" / "sellar" / "sellar_idf.yaml"


def _interrupted_bag(bag: Path, after: int) -> None:
    """An in-process IDF Sellar run stopped after ``after`` records, as by a signal: no answers stored."""
    interrupted_run(SELLAR_IDF, bag, after)


def test_idf_records_hold_the_couplings_and_history_keeps_them_apart(tmp_path):
    from bev_mdo.bag.history import history, to_csv

    _interrupted_bag(tmp_path / "b", after=3)
    rows = history(tmp_path / "b")
    assert len(rows) == 3
    for r in rows:
        assert set(r["design"]) == {"z1", "z2", "x"} and set(r["couplings"]) == {"y1", "y2"}
    assert rows[0]["feasible"]  # the config's start, with the couplings of an MDA there
    header = to_csv(rows).splitlines()[0].split(",")
    assert {"design.z1", "coupling.y1", "coupling.y2"} <= set(header) and "design.y1" not in header


def test_an_interrupted_idf_run_resumes_at_its_last_record_couplings_included(tmp_path, capsys):
    from bev_mdo.bag.history import history, last_iterate

    old, new = tmp_path / "old", tmp_path / "new"
    _interrupted_bag(old, after=3)
    _, start, k = last_iterate(old)
    last = history(old)[-1]
    assert k == last["iteration"] == 2 and not last["feasible"]  # SLSQP's second step: couplings not yet consistent
    assert start == {**last["design"], **last["couplings"]}
    assert main(["resume", str(old), "--transport", "inprocess", "--output", str(new), "--quiet"]) == 0
    capsys.readouterr()
    first = history(new)[0]
    assert first["design"] == last["design"] and first["couplings"] == last["couplings"]
    assert first["objective"] == last["objective"] and first["max_violation"] == last["max_violation"]


def test_a_start_given_to_idf_begins_with_consistent_couplings():
    """x0 of design variables only (a sweep's best design resumed, each of --starts): an MDA there sets the
    couplings, so IDF's iteration 0 is the point MDF's is, consistent and feasible alike."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.driver import run_optimization
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    config = RunConfig.load(SELLAR_IDF)
    x0 = {"z1": 2.0, "z2": 0.5, "x": 0.5}
    recs = {}
    for formulation in ("idf", "mdf"):
        ev = InProcessEvaluator(config.disciplines)
        first = []
        run_optimization(config.settings, ev, formulation=formulation, x0=x0,
                         callback=lambda rec: first.append(rec) if not first else None)
        recs[formulation] = first[0]
    idf, mdf = recs["idf"], recs["mdf"]
    assert idf["design"] == mdf["design"] == x0
    assert idf["feasible"] and idf["max_violation"] == pytest.approx(mdf["max_violation"], abs=1e-9)
    assert idf["objective"] == pytest.approx(mdf["objective"], rel=1e-9)
    assert "couplings" not in mdf


def test_idf_takes_a_start_for_its_couplings_and_names_them_when_refused():
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.driver import run_optimization
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    config = RunConfig.load(SELLAR_IDF)
    first = []
    run_optimization(config.settings, InProcessEvaluator(config.disciplines), formulation="idf",
                     x0={"z1": 2.0, "z2": 0.5, "x": 0.5, "y1": 4.0, "y2": 5.0},
                     callback=lambda rec: first.append(rec) if not first else None)
    assert first[0]["couplings"] == {"y1": 4.0, "y2": 5.0} and not first[0]["feasible"]
    with pytest.raises(ValueError, match=r"x0 names \['y3'\] are not design variables .* or couplings \['y1', 'y2'\]"):
        run_optimization(config.settings, InProcessEvaluator(config.disciplines), formulation="idf",
                         x0={"y3": 1.0})


def test_the_report_of_an_inconsistent_idf_iterate_says_why_it_is_infeasible(tmp_path):
    """Its record infeasible by a consistency residual alone: report.md said "What holds the design" (its
    constraints and bounds hold) beside "feasible False"."""
    from bev_mdo.bag.history import history
    from bev_mdo.bag.report import report

    _interrupted_bag(tmp_path / "b", after=3)
    last = history(tmp_path / "b")[-1]
    assert not last["feasible"] and last["max_violation"] > 1e-4
    report(tmp_path / "b")
    md = (tmp_path / "b" / "report.md").read_text()
    assert "## Why the last recorded iterate is infeasible" in md and "## What holds" not in md
    for c, v in last["couplings"].items():  # each coupling off its disciplines' value, both values named
        assert f"- not consistent: {c} is {v:.6g} in the optimiser's variables, " in md, md


def test_an_inconsistent_idf_iterate_below_the_reports_own_threshold_is_still_named(tmp_path, monkeypatch):
    """The record's residual is scaled by each coupling's scale, the report's comparison by its value: where only
    the record's exceeds the tolerance, its largest violation is named as a consistency residual (a review)."""
    from bev_mdo.bag import report as rep
    from bev_mdo.bag.history import history

    _interrupted_bag(tmp_path / "b", after=3)
    last = history(tmp_path / "b")[-1]
    monkeypatch.setattr(rep, "_inconsistent", lambda row, final, tol: [])
    rep.report(tmp_path / "b")
    md = (tmp_path / "b" / "report.md").read_text()
    assert (f"- not consistent: the record's largest violation {last['max_violation']:.3g} is in none of its "
            "constraints or bounds, so it is an IDF consistency residual") in md, md
