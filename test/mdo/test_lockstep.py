"""Jobs in lockstep over one evaluator (bev_mdo.mdo.lockstep), and multi-start batched with it: the same
results as one start after another, in fewer evaluator waves; a job's error and a signal on the
serving thread end every job and are re-raised."""
from __future__ import annotations

import threading
from pathlib import Path

import numpy as np
import pytest

from bev_mdo.config import resolve_disciplines
from bev_mdo.mdo.discipline import EvalResult, PointError
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.lockstep import rows, run_lockstep
from bev_mdo.mdo.multistart import run_starts
from bev_mdo.testing import example_config

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "sellar"


class Counting(InProcessEvaluator):
    """The in-process evaluator, counting the rows of every call it serves."""

    def __init__(self, disciplines):
        super().__init__(disciplines)
        self.rows_per_call: list[int] = []
        self.threads: set[str] = set()

    def evaluate(self, calls, partials=False):
        self.threads.add(threading.current_thread().name)
        self.rows_per_call += [len(next(iter(inputs.values()))) for _, inputs in calls]
        return super().evaluate(calls, partials)


@pytest.mark.parametrize("form", ["mdf", "idf"])
def test_batched_starts_reach_what_each_start_reaches_alone_in_fewer_waves(form):
    config = example_config(EXAMPLES / f"sellar_{form}.yaml")
    out = {}
    for batched in (False, True):
        ev = Counting(resolve_disciplines(config))
        seen = []
        res = run_starts(config, ev, 5, seed=2, batched=batched, callback=lambda rec: seen.append(rec))
        out[batched] = (res, ev, seen)
    (seq, ev_seq, rec_seq), (bat, ev_bat, rec_bat) = out[False], out[True]
    for a, b in zip(seq.multistart["results"], bat.multistart["results"]):
        assert b["objective"] == pytest.approx(a["objective"], rel=1e-9)
        assert b["verdict"] == a["verdict"] and b["reached_best"] == a["reached_best"]
    assert bat.objective == pytest.approx(seq.objective, rel=1e-9) and bat.multistart["batched"]
    # every record is emitted, on the calling thread, with one running iteration number
    assert len(rec_bat) == len(rec_seq)
    assert [r["iteration"] for r in rec_bat] == list(range(len(rec_bat)))
    assert ev_bat.threads == {threading.current_thread().name}
    # the same rows reached the disciplines, in fewer, larger calls
    assert sum(ev_bat.rows_per_call) == sum(ev_seq.rows_per_call)
    assert ev_bat.waves < ev_seq.waves and max(ev_bat.rows_per_call) > max(ev_seq.rows_per_call)


def test_rows_slices_outputs_partials_and_point_errors():
    res = EvalResult({"y": np.arange(5.0)}, np.array([True, False, True, True, False]), "",
                     extra={"partials": {("y", "x"): np.arange(5.0) * 2}},
                     point_errors={1: PointError("d: y is NaN", "x=1"), 4: PointError("d: y is NaN", "x=4")})
    part = rows(res, 1, 4)
    assert part.outputs["y"].tolist() == [1.0, 2.0, 3.0] and part.ok.tolist() == [False, True, True]
    assert part.extra["partials"][("y", "x")].tolist() == [2.0, 4.0, 6.0]
    assert list(part.point_errors) == [0] and "y is NaN" in part.error


def test_a_jobs_error_is_re_raised_after_the_others_finish():
    config = example_config(EXAMPLES / "sellar_mdf.yaml")
    ev = InProcessEvaluator(resolve_disciplines(config))
    calls = [("sellar1", {"z1": np.array([2.0]), "z2": np.array([1.0]), "x": np.array([1.0]),
                          "y2": np.array([1.0])})]
    finished = []

    def good(lock):
        for _ in range(5):
            lock.evaluate(calls)
        finished.append(True)
        return "done"

    def bad(lock):
        lock.evaluate(calls)
        raise RuntimeError("this start broke")

    with pytest.raises(RuntimeError, match="this start broke"):
        run_lockstep(ev, [good, bad, good])
    assert finished == [True, True]


def test_an_exception_on_the_serving_thread_stops_every_job():
    config = example_config(EXAMPLES / "sellar_mdf.yaml")

    class Interrupted(InProcessEvaluator):
        def __init__(self, discs):
            super().__init__(discs)
            self.served = 0

        def evaluate(self, calls, partials=False):
            self.served += 1
            if self.served == 3:
                raise KeyboardInterrupt  # as a SIGINT handler raises it on the main thread
            return super().evaluate(calls, partials)

    ev = Interrupted(resolve_disciplines(config))
    emitted = []
    with pytest.raises(KeyboardInterrupt):
        run_starts(config, ev, 4, seed=0, callback=emitted.append)
    # the records made before the signal still reach the callback (a bag keeps them)
    assert [r["iteration"] for r in emitted] == list(range(len(emitted)))
    assert not [t for t in threading.enumerate() if t.name.startswith("lockstep-")]


def test_a_job_asking_after_the_run_was_stopped_is_refused():
    config = example_config(EXAMPLES / "sellar_mdf.yaml")
    ev = InProcessEvaluator(resolve_disciplines(config))

    class Boom(Exception):
        pass

    def job(lock):
        lock.evaluate([])
        return 1

    class Failing(InProcessEvaluator):
        def evaluate(self, calls, partials=False):
            raise Boom()

    with pytest.raises(Boom):
        run_lockstep(Failing(resolve_disciplines(config)), [job, job])
    assert run_lockstep(ev, [job, job]) == [1, 1]


def test_many_starts_run_on_a_bounded_number_of_threads_with_the_same_results(monkeypatch):
    """--starts 600 started a thread per start and, under a 4 GB address-space limit, failed with "can't
    start new thread" (exit 7). At most MAX_THREADS starts now run at once, each thread taking the next start
    when its own ends; every start's result is the one it reaches with a thread of its own."""
    import bev_mdo.mdo.lockstep as lockstep

    config = example_config(EXAMPLES / "sellar_mdf.yaml")

    class Sampling(Counting):
        def evaluate(self, calls, partials=False):
            self.live = max(getattr(self, "live", 0), threading.active_count())
            self.lockstep_threads = max(getattr(self, "lockstep_threads", 0), sum(
                t.name.startswith("lockstep-") for t in threading.enumerate()))
            return super().evaluate(calls, partials)

    starts, bound = 48, 6
    before = threading.active_count()
    got = {}
    for threads in (starts, bound):  # a thread per start (as before), then a pool of 8
        monkeypatch.setattr(lockstep, "MAX_THREADS", threads)
        ev, seen = Sampling(resolve_disciplines(config)), []
        got[threads] = (run_starts(config, ev, starts, seed=3, callback=seen.append), ev, seen)
    (one_each, ev_each, rec_each), (pooled, ev_pool, rec_pool) = got[starts], got[bound]
    assert ev_each.lockstep_threads == starts and ev_pool.lockstep_threads == bound
    assert ev_pool.live <= before + bound
    assert pooled.multistart["results"] == one_each.multistart["results"]  # every start, exactly
    assert pooled.design == one_each.design and pooled.objective == one_each.objective
    assert len(rec_pool) == len(rec_each) and [r["iteration"] for r in rec_pool] == list(range(len(rec_pool)))
    assert sum(ev_pool.rows_per_call) == sum(ev_each.rows_per_call)
    assert max(ev_pool.rows_per_call) >= bound  # still batched: the pool's starts share each wave
    assert not [t for t in threading.enumerate() if t.name.startswith("lockstep-")]


def test_the_starts_records_come_in_the_same_order_every_run(monkeypatch):
    """The records of one wave were emitted in the order the threads happened to make them: two runs of the
    same --starts wrote their bags' iteration records in different orders. Now job by job in job order."""
    import bev_mdo.mdo.lockstep as lockstep

    config = example_config(EXAMPLES / "sellar_mdf.yaml")
    monkeypatch.setattr(lockstep, "MAX_THREADS", 8)
    streams = []
    for _ in range(3):
        seen = []
        run_starts(config, InProcessEvaluator(resolve_disciplines(config)), 40, seed=5, callback=seen.append)
        streams.append([(r["iteration"], r["objective"], tuple(r["design"].values())) for r in seen])
    assert len(streams[0]) > 40 and all(s == streams[0] for s in streams[1:])
