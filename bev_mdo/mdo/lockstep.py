"""Several independent jobs over one evaluator, their requests merged into one batch per discipline.

Each job (for example one start of a multi-start optimisation) runs on one of at most ``MAX_THREADS``
threads (a thread takes the next job, in order, when its job ends: 600 starts with a thread each ran
out of address space) and calls a :class:`LockstepEvaluator` as it would call the evaluator itself.
A request blocks until every job running has made one, or has finished; the calling thread then merges the waiting requests
(rows of the same discipline with the same inputs are concatenated; data-flow MDAs of the same
disciplines are concatenated), sends them to the real evaluator as one wave, and hands each job its
own rows back. Over ROS this turns N round trips into one; in process, N small batches into one.

Only the thread that called :func:`run_lockstep` talks to the real evaluator (a ROS node's
executor, signal handlers and the bag writer stay on it). The jobs' ``callback`` records (their
iteration records) are queued and emitted on that thread too: at each wave, those made since the last
one, job by job in job order (each job's in the order it made them), so the stream is the same from run
to run whatever the threads' timing.

A job's rows are evaluated exactly as they would be alone, so the results depend on the batch only
through the model's own arithmetic (vectorised models are row-independent).
"""
from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from bev_mdo.mdo.discipline import EvalResult, error_text

# jobs running at once (one thread each, ~8 MB of stack address space apiece); more jobs wait for a thread
MAX_THREADS = 64


class Aborted(Exception):
    """A job's request was not served because the run was stopped (a signal, another job's error)."""


def rows(res: EvalResult, start: int, stop: int) -> EvalResult:
    """Rows ``start:stop`` of ``res`` as a result of its own (point errors renumbered from 0)."""
    pe = {i - start: e for i, e in res.point_errors.items() if start <= i < stop}
    extra = dict(res.extra)
    if "partials" in extra:
        extra["partials"] = {k: np.asarray(v)[start:stop] for k, v in extra["partials"].items()}
    return EvalResult({k: np.asarray(v)[start:stop] for k, v in res.outputs.items()},
                      np.asarray(res.ok)[start:stop], error_text(pe) if pe else res.error, res.compute_time_s,
                      extra, pe)


def _n_rows(inputs: Mapping[str, Any]) -> int:
    return len(np.atleast_1d(next(iter(inputs.values())))) if inputs else 0


class _Request:
    __slots__ = ("kind", "payload", "result", "done")

    def __init__(self, kind: str, payload: tuple):
        self.kind, self.payload, self.result, self.done = kind, payload, None, False


class LockstepEvaluator:
    """The evaluator interface for the jobs of :func:`run_lockstep` (see the module doc)."""

    def __init__(self, inner: Any, jobs: int):
        self.inner = inner
        self._cond = threading.Condition()
        self._live = jobs  # the threads running jobs (each asks for one request at a time)
        self._pending: list[_Request] = []
        self._records: list[tuple[int, Callable[[dict], Any], dict]] = []  # (job, callback, record)
        self._job = threading.local()  # the job index the calling thread runs (run_lockstep sets it)
        self._aborted: BaseException | None = None
        self.waves = 0  # merged waves sent to the real evaluator

    def __getattr__(self, name: str) -> Any:  # specs, counts and whatever else the transport offers
        return getattr(self.inner, name)

    # ------------------------------------------------------------ the jobs' side
    def evaluate(self, calls: list, partials: bool = False) -> list[EvalResult]:
        return self._ask("wave", (list(calls), bool(partials)))

    def evaluate_flow(self, names: Sequence[str], request: Mapping[str, np.ndarray], n: int,
                      partials: bool = False) -> dict[str, EvalResult] | None:
        if getattr(self.inner, "evaluate_flow", None) is None:
            return None
        return self._ask("flow", (tuple(names), dict(request), int(n), bool(partials)))

    def emit(self, callback: Callable[[dict], Any], record: dict) -> None:
        """Queue ``callback(record)`` for the serving thread."""
        with self._cond:
            self._records.append((getattr(self._job, "index", 0), callback, record))

    def _ask(self, kind: str, payload: tuple) -> Any:
        req = _Request(kind, payload)
        with self._cond:
            if self._aborted is not None:
                raise Aborted("the run was stopped") from self._aborted
            self._pending.append(req)
            self._cond.notify_all()
            while not req.done:
                self._cond.wait()
        if isinstance(req.result, BaseException):
            raise Aborted("the run was stopped") from req.result
        return req.result

    @property
    def stopped(self) -> bool:
        """The run was stopped (a signal, the evaluator's error): no job may ask any more."""
        return self._aborted is not None

    def finished(self) -> None:
        """A thread has no more jobs to run."""
        with self._cond:
            self._live -= 1
            self._cond.notify_all()

    # ------------------------------------------------------------ the serving thread's side
    def serve(self) -> None:
        """Serve merged requests until every job has finished; re-raises what stops the serving
        (a signal's exception) after failing every waiting request with it."""
        batch: list[_Request] = []
        try:
            while True:
                with self._cond:
                    while self._live and len(self._pending) < self._live:
                        self._cond.wait(0.2)  # a timeout, so a signal reaches this thread promptly
                    batch, self._pending = self._pending, []
                self.drain_records()  # every live job waits for its request now: none adds a record
                if not batch:
                    if not self._live:
                        return
                    continue
                self._serve(batch)
                with self._cond:
                    for req in batch:
                        req.done = True
                    self._cond.notify_all()
        except BaseException as exc:
            with self._cond:
                self._aborted = exc
                for req in self._pending + [r for r in batch if not r.done]:
                    req.result, req.done = exc, True
                self._pending = []
                self._cond.notify_all()
            raise

    def drain_records(self) -> None:
        """Emit the queued records, job by job in job order (a stable sort: each job's in the order made)."""
        with self._cond:
            records, self._records = self._records, []
        for _, callback, record in sorted(records, key=lambda r: r[0]):
            callback(record)

    def _serve(self, batch: list[_Request]) -> None:
        waves: dict[bool, list[_Request]] = {}
        flows: dict[tuple, list[_Request]] = {}
        for req in batch:
            if req.kind == "wave":
                waves.setdefault(req.payload[1], []).append(req)
            else:
                names, request, _, partials = req.payload
                flows.setdefault((names, partials, tuple(sorted(request))), []).append(req)
        for partials, reqs in waves.items():
            self._wave(reqs, partials)
        for (names, partials, _), reqs in flows.items():
            self._flow(reqs, list(names), partials)

    def _wave(self, reqs: list[_Request], partials: bool) -> None:
        merged: dict[tuple, list[tuple[_Request, int, Mapping]]] = {}  # (name, input keys) -> its shares
        for req in reqs:
            for j, (name, inputs) in enumerate(req.payload[0]):
                merged.setdefault((name, tuple(sorted(inputs))), []).append((req, j, inputs))
        calls = [(name, {k: np.concatenate([np.atleast_1d(np.asarray(s[2][k], dtype=float)) for s in shares])
                         for k in keys}) for (name, keys), shares in merged.items()]
        self.waves += 1
        results = self.inner.evaluate(calls, partials=True) if partials else self.inner.evaluate(calls)
        for req in reqs:
            req.result = [None] * len(req.payload[0])
        for shares, res in zip(merged.values(), results):
            start = 0
            for req, j, inputs in shares:
                n = _n_rows(inputs)
                req.result[j] = rows(res, start, start + n)
                start += n

    def _flow(self, reqs: list[_Request], names: list[str], partials: bool) -> None:
        keys = sorted(reqs[0].payload[1])
        request = {k: np.concatenate([np.atleast_1d(np.asarray(r.payload[1][k], dtype=float)) for r in reqs])
                   for k in keys}
        n = sum(r.payload[2] for r in reqs)
        self.waves += 1
        got = (self.inner.evaluate_flow(names, request, n, partials=True) if partials
               else self.inner.evaluate_flow(names, request, n))
        start = 0
        for req in reqs:
            m = req.payload[2]
            req.result = None if got is None else {d: rows(res, start, start + m) for d, res in got.items()}
            start += m


def run_lockstep(evaluator: Any, jobs: Sequence[Callable[[LockstepEvaluator], Any]],
                 max_threads: int | None = None) -> list[Any]:
    """Run every ``job(lockstep_evaluator)``, at most ``max_threads`` (default ``MAX_THREADS``) at once: each
    thread takes the next job in order when its job ends; their requests merged (module doc); their return
    values in job order. A job's exception is re-raised here once all have ended; an exception on this
    thread (a signal) stops every job and is re-raised."""
    threads_wanted = max(1, min(len(jobs), MAX_THREADS if max_threads is None else max_threads))
    lockstep = LockstepEvaluator(evaluator, threads_wanted)
    out: list[Any] = [None] * len(jobs)
    errors: list[tuple[int, BaseException]] = []
    order = iter(range(len(jobs)))
    taking = threading.Lock()

    def work() -> None:
        try:
            while not lockstep.stopped:
                with taking:
                    i = next(order, None)
                if i is None:
                    return
                lockstep._job.index = i
                try:
                    out[i] = jobs[i](lockstep)
                except BaseException as exc:  # noqa: BLE001 - handed to the serving thread
                    errors.append((i, exc))
        finally:
            lockstep.finished()

    threads = [threading.Thread(target=work, name=f"lockstep-{k}", daemon=True) for k in range(threads_wanted)]
    for t in threads:
        t.start()
    try:
        lockstep.serve()
    finally:
        for t in threads:
            t.join(timeout=30)
        lockstep.drain_records()
    real = [(i, e) for i, e in sorted(errors, key=lambda t: t[0]) if not isinstance(e, Aborted)]
    if real:
        raise real[0][1]
    if errors:
        raise errors[0][1]
    return out
