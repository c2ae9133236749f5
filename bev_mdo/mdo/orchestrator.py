"""The orchestration of a distributed evaluation, independent of any transport (no ROS import).

``Orchestrator`` implements the engine's Evaluator interface (evaluator.py) over a transport that
sends requests and receives answers (the ROS one: ros/evaluator.py): it decides what is sent and
when, and what an answer means. A wave of calls is one request per (discipline, batch); a
feed-forward MDA is ONE data-flow request naming its disciplines (flow.py); with worker pools
(pool.py) a batch, or a data-flow MDA, is cut into row shares, each addressed to one instance,
and the answers are joined in row order. Every request gets a fresh evaluation id in the ledger
(ledger.py), which accepts at most one answer per (id, discipline); a late request is re-sent
or given up as retry.py decides, and the points of a request that never got an answer fail
(NaN, infeasible) with an error naming the discipline.

A transport subclass provides:
- ``_request(eid, discipline, batch, tag, *, flow, iteration, attempt, partials)``: a request
  object with the fields ``evaluation_id``, ``attempt``, ``partials``, ``flow``,
  ``header.frame_id`` (the binding its answer must echo) and ``inputs.batch_size``;
- ``_tag(names, targets=None)``: the binding of a request to `names` (and, for a pool's share,
  to one instance of some of them: ``targets``);
- ``_send(p)``: send the request of ``p`` (a retry.Sent) and set ``p.sent_ns``;
- ``_take_until(deadline, once=False)``: take answers (each handed to ``_accept``) until nothing
  is pending or the monotonic `deadline` (s) passed; with ``once`` one wait at most;
- ``_live(name)``: the instances a batch of `name` is split among (None: one request);
  ``_present_instances(name)``: (accepted instances of `name` reachable now, readers);
- ``_poll_info()``: take the disciplines' declarations that arrived meanwhile;
- ``log``: a logger with ``info``, ``warning`` and ``error``.
"""
from __future__ import annotations

import contextlib
import copy
import itertools
import secrets
import time
from collections import Counter
from typing import Callable, Mapping, Sequence

import numpy as np

from bev_mdo.mdo import flow, pool as pools, retry
from bev_mdo.mdo.discipline import (EvalResult, PointError, describe_row, error_text, failed,
                                   first_error_line)
from bev_mdo.mdo.evaluator import DisciplineSpec
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.ledger import Ledger
from bev_mdo.mdo.vectors import ShapeError, broken_contract

# A data-flow share has at least this many rows. Every discipline of the MDA computes each share
# on its own, and numpy reduces a batch of ONE row in another order than a batch of several (a
# contiguous axis is summed pairwise): the acceleration model differs in the last bit between
# n = 1 and n > 1. Shares of two rows or more keep the joined result bitwise the single-request one.
FLOW_MIN_ROWS = 2

# How long past its retries a request still waits for a discipline whose node the launcher is restarting
# (``Orchestrator.recovering``): the watchdog's kill (launcher: 7 s after the 12 s lease) and a restart
# (a loaded host's energy_node took over 60 s to declare itself). The bound on a node that never comes back.
RECOVERY_S = 90.0


# What a run reports of its own evaluations; a sub-run through the same evaluator leaves it as it was.
_RUN_COUNTERS = ("counts", "first_errors", "accepted", "retried", "unresponsive", "flows", "flow_shares")


class Orchestrator:
    """Waves, data-flow MDAs, pools' shares, retries and the ledger over a transport (a subclass)."""

    def __init__(self, *, run_id: str, timeout_s: float, retries: int, pool_mode: str = "share",
                 pool_data_flow: bool = True, pool_min_rows=1):
        self.run_id = run_id
        self.timeout_s = timeout_s
        self.retries = retries
        self.specs: dict[str, DisciplineSpec] = {}
        self.counts: Counter[str] = Counter()      # points evaluated per discipline
        self.first_errors: dict[str, str] = {}     # discipline -> its first error (shown once)
        self.accepted: list[tuple[int, str, str, int]] = []  # (evaluation id, discipline, instance, attempt)
        # ids, outstanding/answered/reassigned requests and why answers were dropped (ledger.py)
        # ids from a random start (below 2**52: exact as a float): two coordinators given one run id (by hand,
        # -p run_id:= typed twice) each took the other's answers to its own ids 1, 2, ... (wrong results)
        self.ledger: Ledger[retry.Sent] = Ledger(lambda p: p.request.header.frame_id,
                                                 first_id=secrets.randbelow(2**52) + 1)
        self.dropped: Counter[str] = self.ledger.dropped  # other_run / stale / duplicate / malformed / ...
        self._pending = self.ledger.pending   # (evaluation id, discipline) -> outstanding retry.Sent
        self.retried = 0
        # the optimiser iteration the requests belong to: how many iteration records were published
        # before them (0: the start point); the coordinator moves it on after each record
        self.iteration = 0
        self.unresponsive: set[str] = set()  # disciplines that let every attempt of a request time out
        self._results: dict[int, EvalResult] = {}
        self._contract = ""  # a discipline's broken contract answered in this wave (raised at its end: _checked)
        self.coupling_sources: dict[str, dict[str, str]] = {}  # discipline -> {coupling input: source}
        self.flows = 0  # MDAs served by data flow (one request each)
        self._flow_plans: dict[tuple, dict | None] = {}
        # Worker pools (pool.py): several accepted instances of a discipline share each batch.
        self.pool_mode = pools.validate_mode(pool_mode)
        self.pools: dict[str, pools.Pool] = {}
        self._shares = retry.Shares()                       # answers of row shares, joined in row order
        self._share_targets: dict[int, Mapping[str, str]] = {}  # data-flow share -> {discipline: instance}
        self._batches: dict[int, tuple[str, Mapping]] = {}  # wave index -> (discipline, batch) of a pool's call
        self.flow_shares = 0  # data-flow requests sent as row shares of pooled MDAs
        # False: an MDA with a pool runs in waves (only the pooled disciplines see shares; the
        # others get the whole batch once; docs/scaling.md)
        self.pool_data_flow = pool_data_flow
        self.pool_min_rows = pool_min_rows
        # discipline -> whether the launcher is restarting a node of it (Launcher.recovering); None: no launcher
        self.recovering: Callable[[str], bool] | None = None

    @contextlib.contextmanager
    def sub_run(self, suffix: str):
        """Evaluate as the derived run ``<run>-<suffix>`` (the baseline, through the run's own nodes):
        its requests carry that run id, which the run's nodes serve, and only its answers are taken.
        Afterwards the run id is the run's again, and what the run reports of its own evaluations
        (points, retries, data-flow MDAs, errors, unresponsive disciplines) is as it was before;
        answers dropped and instances refused meanwhile count as the run's."""
        saved = {k: copy.copy(getattr(self, k)) for k in _RUN_COUNTERS}
        run_id, self.run_id = self.run_id, f"{self.run_id}-{suffix}"
        try:
            yield self
        finally:
            self.run_id = run_id
            for k, v in saved.items():
                setattr(self, k, v)

    @property
    def policy(self) -> retry.Policy:
        """When a request is late and how often it is re-sent (retry.py)."""
        return retry.Policy(self.timeout_s, self.retries)

    @property
    def _next_id(self) -> int:  # the evaluation id the next request gets
        return self.ledger.next_id

    def flow_plan(self, names: Sequence[str]) -> dict[str, dict[str, str]] | None:
        """{discipline: {coupling input: source}} for a data-flow MDA of `names`, or None when some
        node reads a coupling input from another producer than this graph's (or declared nothing),
        or when the graph has a loop (data flow serves feed-forward graphs only)."""
        key = tuple(sorted(names))
        if key not in self._flow_plans:
            plan = None
            if all(n in self.specs for n in names):
                producer = {v: n for n in names for v in self.specs[n].outputs}
                plan = {n: flow.sources_of(self.specs[n].inputs, producer, n) for n in names}
                # exact: a node with a declared source outside this MDA does not read the request
                if any(self.coupling_sources.get(n, {}) != plan[n] for n in names):
                    plan = None
                elif CouplingGraph((n, self.specs[n].inputs, self.specs[n].outputs) for n in names).cycles:
                    plan = None  # a loop: no node of it can start (the MDA iterates it hub and spoke)
            self._flow_plans[key] = plan
        return self._flow_plans[key]

    # -- evaluation ----------------------------------------------------------------
    def evaluate(self, calls: Sequence[tuple[str, Mapping[str, np.ndarray]]], iteration: int | None = None,
                 partials: bool = False) -> list[EvalResult]:
        """Evaluate one wave: every (discipline, batch) call concurrently. Never raises for a slow node.
        With ``partials`` the nodes return their disciplines' analytic partials too."""
        iteration = self.iteration if iteration is None else int(iteration)
        self._results = {}
        self._shares, self._batches = retry.Shares(), {}
        self._poll_info()
        shared = False
        for i, (name, batch) in enumerate(calls):
            if name in self.unresponsive:
                n = len(next(iter(batch.values()), ()))
                self._results[i] = self._failed(retry.Sent(i, name, None, n, 0),
                                                f"{name}: did not answer earlier requests (hung or gone)")
                continue
            req = self._request(self.ledger.next_id, name, batch, self._tag([name]), iteration=iteration,
                                partials=partials)
            n = int(req.inputs.batch_size)
            # a batch is shared among a pool's instances; not when partials are asked (shares carry none)
            live = self._live(name) if n > 1 and not partials else None
            if live and len(live) > 1:
                shared = True
                self._send_shares(i, name, batch, iteration, 0, n, live)
                continue
            p = self.ledger.open(self.ledger.new_id(), name, retry.Sent(i, name, req, n, 0, inputs=batch))
            self._send(p)
        if shared:
            self._await_pool(iteration)
            for i in self._shares.indices():  # every pooled call's shares, joined in row order
                self._results[i] = self._join(i, calls[i][0])
        else:
            self._await()
        return self._checked([self._results[i] for i in range(len(calls))])

    def evaluate_flow(self, names: Sequence[str], request: Mapping[str, np.ndarray], n: int,
                      partials: bool = False) -> dict | None:
        """One feed-forward MDA as ONE data-flow request; None when the nodes cannot serve it that way."""
        plan = self.flow_plan(names)
        if plan is None or self.unresponsive.intersection(names):
            return None
        self._flow_topics(names)
        self._results = {}
        self._poll_info()
        pooled = {d: live for d in names if (live := self._live(d) if n > 0 else None) and len(live) > 1}
        if pooled:
            if not self.pool_data_flow:
                return None
            return self._checked(self._flow_shares(names, plan, request, n, bool(partials), pooled))
        eid = self.ledger.new_id()
        req = self._request(eid, "", request, self._tag(names), flow=names, partials=partials)
        sent = [self.ledger.open(eid, name, retry.Sent(i, name, req, n, 0, flow=True, inputs=request)) for i, name in enumerate(names)]
        self._send(sent[0])  # one message for every discipline
        self._await()
        self.flows += 1
        out = {name: self._results[i] for i, name in enumerate(names)}
        answered = {d for e, d, _, _ in self.accepted[-len(names):] if e == eid}
        self.counts.update(flow.rows_per_discipline(plan, out, n, [d for d in names if d in answered]))
        return self._checked(out)

    def _flow_topics(self, names: Sequence[str]) -> None:
        """Make ready what a data-flow MDA of `names` is sent and answered on (the transport's)."""

    def _accept(self, key: tuple[int, str], p: retry.Sent, res: EvalResult, instance: str) -> None:
        """Take `res` as the answer of the ledger entry `p` (`key`): counted, logged in `accepted`."""
        if res.error and not self._contract:  # (the run stops on a broken contract with its own line)
            self._first_error(p.discipline, res.error)
        if not p.flow:  # a data-flow MDA counts the rows each discipline evaluated at the end
            self.counts[p.discipline] += p.n
        self.accepted.append((key[0], key[1], instance, int(p.request.attempt)))
        self.ledger.settle(*key)
        if p.target:
            self._pool(p.discipline).record(p.target, p.n, (time.monotonic_ns() - p.sent_ns) * 1e-9)
        self._place(key, p, res)

    def _place(self, key: tuple[int, str], p: retry.Sent, res: EvalResult) -> None:
        """Keep `res` as the result of `p`: a row share's (of a pool's call, or of a data-flow MDA:
        _flow_shares) until its shares are joined, else the call's."""
        if p.start >= 0:
            self._shares.add(key[0], p.index, p.start, res)
        else:
            self._results[p.index] = res

    def _first_error(self, discipline: str, error: str) -> None:
        """Name a discipline's first failure on the console (the node's log has the rest)."""
        if discipline not in self.first_errors:
            self.first_errors[discipline] = line = first_error_line(error)
            self.log.error(f"discipline {discipline!r} failed: {line}")

    def _failed(self, p: retry.Sent, error: str) -> EvalResult:
        spec = self.specs.get(p.discipline)
        return failed(spec.outputs if spec else (), p.n, error)

    def _rejected(self, p: retry.Sent, error: str) -> EvalResult:
        """The answer to `p` when its discipline refused the request (``error``: why): its points fail, named. A
        refusal for the discipline's own mistake (an output of the wrong shape, one left out: a user's class
        breaking its contract) is kept, and raised once the wave is answered (_checked), as in process."""
        self._contract = self._contract or broken_contract(p.discipline, error) or ""
        return self._failed(p, error or f"{p.discipline}: request rejected")

    def _checked(self, out):
        """`out`, the results of a wave (or data-flow MDA) every answer of which is in, unless a discipline broke
        its contract there: then the ShapeError an in-process run stops with, its one line (exit 2 in the CLI)."""
        why, self._contract = self._contract, ""
        if why:
            raise ShapeError(why)
        return out

    def _join(self, index: int, name: str) -> EvalResult:
        """The answered shares of call `index` (discipline `name`) joined in row order."""
        spec = self.specs.get(name)
        return self._shares.join(index, spec.outputs if spec else None)

    # -- retries -------------------------------------------------------------------
    def _await(self) -> None:
        """Wait for every pending result; re-send what times out; fail what never answers. A discipline the launcher
        reports restarting (``recovering``, read after every timeout) is waited for until it answers: past the retries
        its request is re-sent every ``timeout_s`` for up to RECOVERY_S more, and twice after (docs/security.md)."""
        budget_end, back, restarted = None, 0, set()
        for attempt in itertools.count():
            self._take_until(time.monotonic() + self.timeout_s)
            for key, p in list(self._pending.items()):
                if p.discipline in self.unresponsive:  # found hung meanwhile (mark_hung): no retry
                    self._give_up(key, p)
            if not self._pending:
                break
            # Once seen restarting, a discipline stays so until it answers: the launcher's flag is off in moments
            # of a restart (a look at the end of the budget missed it), and is off again once the new node is back
            # on the graph, before its subscriptions match and its first answer (numba compiles) comes.
            restarted |= self._restarting()
            if attempt >= self.retries:
                budget_end = budget_end or time.monotonic()
                waiting = time.monotonic() < budget_end + RECOVERY_S and any(
                    p.discipline in restarted for p in self._pending.values())
                back = 2 if waiting else back - 1
                if back < 0:
                    break
            for p, late in retry.resend_round(self._pending, attempt + 1):
                self.retried += len(late)
                p.request.attempt = p.tries
                why = (f"retry {attempt + 1}/{self.retries}" if attempt < self.retries else
                       f"retry {attempt + 1}: its node is being restarted (up to {RECOVERY_S:g} s more)")
                self.log.warning(f"no answer from {late} for evaluation {p.request.evaluation_id}{retry.points(p)} "
                                 f"after {self.timeout_s:g} s; {why}")
                self._send(p)
        unanswered = dict(self._pending)
        for key, p in unanswered.items():
            self._give_up(key, p)
        for d in retry.hung(unanswered, self._sources_of):
            self.mark_hung(d)

    def _restarting(self) -> set[str]:
        """The pending disciplines whose node the launcher is restarting now (``recovering``)."""
        pending = {p.discipline for p in self._pending.values()}
        return {d for d in pending if self.recovering(d)} if self.recovering is not None else set()

    def mark_hung(self, d: str) -> None:
        """Discipline `d` let every attempt time out (or, called in this process, overran the same budget:
        mdo/timed.py): it is hung (or gone). Said once; its later requests fail at once instead of
        waiting the whole timeout each time."""
        if d not in self.unresponsive:
            self.unresponsive.add(d)
            self.log.error(f"discipline {d!r} did not answer within {self.retries + 1} x {self.timeout_s:g} s: "
                           "its points fail, and so do its later requests, at once")

    def _give_up(self, key: tuple[int, str], p: retry.Sent) -> None:
        """Every attempt of `p` timed out: its points fail, named (a late answer is then dropped as a
        duplicate, never used)."""
        res = self._failed(p, self.policy.no_answer(p.discipline))
        spec, cols = self.specs.get(p.discipline), p.inputs or {}
        cols = {k: np.asarray(v) for k, v in cols.items() if spec is None or k in spec.inputs} or cols
        if cols and p.n:  # each point named with its inputs, as a point that raises is
            res.point_errors = {i: PointError(res.error, describe_row(cols, i)) for i in range(p.n)}
            res.error = error_text(res.point_errors)
        self._first_error(p.discipline, res.error)
        self.ledger.close(key)
        self._place(key, p, res)

    def _sources_of(self, p: retry.Sent) -> set[str]:
        """The sources a data-flow entry's discipline reads from (none for hub and spoke)."""
        return set(((self.flow_plan(list(p.request.flow)) or {}).get(p.discipline) or {}).values())

    # -- worker pools (pool.py) -----------------------------------------------------
    def _pool(self, name: str) -> pools.Pool:
        pool = self.pools.get(name)
        if pool is None:
            pool = self.pools[name] = pools.Pool(name)
        return pool

    def pool_summary(self) -> dict[str, dict[str, dict]]:
        """{discipline: {instance: work, throughput, failures}} for every discipline with a pool."""
        return {d: {i: s.to_dict() for i, s in sorted(p.stats.items())}
                for d, p in sorted(self.pools.items()) if any(s.shares or s.failures for s in p.stats.values())}

    def _send_shares(self, index: int, name: str, batch: Mapping[str, np.ndarray], iteration: int,
                     first: int, n: int, live: list[str], tries: int = 0) -> None:
        """Send rows first..first+n of `batch` as one share per instance in `live`."""
        self._batches[index] = (name, batch)
        for inst, a, b in self._pool(name).split(n, live, min_rows=pools.min_rows_of(self.pool_min_rows, name)):
            eid = self.ledger.new_id()
            rows = {k: np.asarray(v)[first + a:first + b] for k, v in batch.items()}
            req = self._request(eid, name, rows, self._tag([name], {name: inst}), iteration=iteration, attempt=tries)
            p = self.ledger.open(eid, name, retry.Sent(index, name, req, b - a, 0, target=inst, start=first + a,
                                                       tries=tries, inputs=rows))
            self._send(p)

    def _wait_shares(self, checked: float, check_s: float) -> tuple[int, set[tuple[str, str]], float]:
        """Wait for results of the pending shares until the next one times out, at most `check_s`;
        every `check_s` also find the (discipline, instance) pairs whose instance left the
        transport. Returns (now in ns, those pairs, the time they were last checked)."""
        now = time.monotonic()
        self._take_until(min(self.policy.due_s(self._pending.values()), now + check_s), once=True)
        now_ns = time.monotonic_ns()
        now = now_ns * 1e-9
        gone: set[tuple[str, str]] = set()
        if now - checked >= check_s:
            checked = now
            for name in {p.discipline for p in self._pending.values() if p.target}:
                present, _ = self._present_instances(name)
                gone |= {(name, p.target) for p in self._pending.values()
                         if p.discipline == name and p.target and p.target not in present}
        return now_ns, gone, checked

    def _await_pool(self, iteration: int, check_s: float = 0.1) -> None:
        """Wait for a wave holding shares. A share whose instance times out or leaves the ROS graph
        is split again among the other live instances (new evaluation ids: a late answer to the
        old one is dropped as ``late_share``, never used), up to ``retries`` times per row
        (retry.share_steps decides)."""
        checked = 0.0
        while self._pending:
            now_ns, gone, checked = self._wait_shares(checked, check_s)
            for step in retry.share_steps(self.policy, self._pending, now_ns, gone):
                p, key = step.sent, step.key
                if key not in self._pending:
                    continue
                if step.blame:
                    self._pool(p.discipline).fail(p.target, p.n)
                if step.action == "give_up":
                    self._give_up(key, p)
                    continue
                self.retried += 1
                if step.action == "resend":  # a whole batch of a discipline without a pool: re-send as before
                    p.tries += 1
                    p.request.attempt = p.tries
                    self.log.warning(f"no answer from {[p.discipline]} for evaluation "
                                     f"{p.request.evaluation_id}{retry.points(p)}; retry {p.tries}/{self.retries}")
                    self._send(p)
                    continue
                self.ledger.reassign(key)
                live = self._live(p.discipline) or []
                if not live:  # every instance failed: try them all again rather than give up early
                    live = sorted(self._present_instances(p.discipline)[0]) or [p.target]
                self.log.warning(
                    f"{p.discipline} instance {p.target!r} {step.why} holding {p.n} design(s){retry.points(p)}; "
                    f"re-sent to {live} (retry {p.tries + 1}/{self.retries})")
                name, batch = self._batches[p.index]
                self._send_shares(p.index, name, batch, iteration, p.start, p.n, live, tries=p.tries + 1)

    # -- data flow with pools ------------------------------------------------------
    def _flow_shares(self, names: Sequence[str], plan: Mapping[str, Mapping[str, str]],
                     request: Mapping[str, np.ndarray], n: int, partials: bool,
                     pooled: Mapping[str, list[str]]) -> dict:
        """One data-flow MDA over pools: its rows are cut into shares (in proportion to the
        throughput of the largest pool's instances), and each share is ONE data-flow request in
        which every pooled discipline is addressed to one of its instances (the largest pool: one
        instance per share; a smaller pool: its instances in turn). So each instance evaluates
        its own rows, a consumer joins its sources' results of the same share as without pools,
        and the coordinator joins every discipline's shares in row order. A share not answered
        within the timeout, or whose instance left the graph, is re-sent whole (new evaluation id,
        other instances) and its old answers are dropped (``late_share``; retry.py decides)."""
        lead = max(pooled, key=lambda d: (len(pooled[d]), d))
        self._shares, self._share_targets = retry.Shares(), {}
        for j, (inst, a, b) in enumerate(self._pool(lead).split(
                n, pooled[lead], min_rows=max(FLOW_MIN_ROWS, pools.min_rows_of(self.pool_min_rows, lead)))):
            targets = {d: inst if d == lead else live[j % len(live)] for d, live in pooled.items()}
            self._send_flow_share(names, request, a, b, targets, partials, 0)
        gave_up = self._await_flow_shares(names, plan, request, partials)
        out = {name: self._join(i, name) for i, name in enumerate(names)}
        self.flows += 1
        self.counts.update(flow.rows_per_discipline(plan, out, n, [d for d in names if d not in gave_up]))
        self._shares, self._share_targets = retry.Shares(), {}
        return out

    def _send_flow_share(self, names: Sequence[str], request: Mapping[str, np.ndarray], a: int, b: int,
                         targets: Mapping[str, str], partials: bool, tries: int) -> None:
        eid = self.ledger.new_id()
        rows = {k: np.asarray(v)[a:b] for k, v in request.items()}
        req = self._request(eid, "", rows, self._tag(names, targets), flow=names, attempt=tries, partials=partials)
        sent = [self.ledger.open(eid, name, retry.Sent(i, name, req, b - a, 0, flow=True,
                                                       target=targets.get(name, ""), start=a, tries=tries,
                                                       inputs=rows))
                for i, name in enumerate(names)]
        self._shares.sent(eid, a, b, tries)
        self._share_targets[eid] = targets
        self.flow_shares += 1
        self._send(sent[0])  # one message for every discipline of the share
        for p in sent[1:]:
            p.sent_ns = sent[0].sent_ns

    def _await_flow_shares(self, names: Sequence[str], plan: Mapping[str, Mapping[str, str]],
                           request: Mapping[str, np.ndarray], partials: bool, check_s: float = 0.1) -> set[str]:
        """Wait for the shares of a pooled data-flow MDA; re-send a share whose instance stalled or
        left (retry.flow_share_steps decides). Returns the disciplines that had rows failed for want
        of an answer."""
        gave_up: set[str] = set()
        checked = 0.0
        while self._pending:
            now_ns, gone, checked = self._wait_shares(checked, check_s)
            for step in retry.flow_share_steps(self.policy, self._pending, now_ns, gone, plan, self._shares.tries):
                for d, t, k in step.blame:
                    self._pool(d).fail(t, k)
                if step.give_up:  # what is missing fails, named
                    for key, p in step.items:
                        self._give_up(key, p)
                        gave_up.add(p.discipline)
                    continue
                a, b, tries = self._shares.meta[step.eid]
                for key, _ in step.items:  # the share is re-sent whole; answers to the old one are dropped
                    self.ledger.reassign(key)
                for i in self._shares.drop(step.eid):
                    self.ledger.late.add((step.eid, names[i]))
                self.retried += 1
                targets = {}
                for d in self._share_targets.pop(step.eid, {}):  # the disciplines the share addressed
                    live = self._live(d) or sorted(self._present_instances(d)[0])
                    if live:
                        targets[d] = retry.pick(live, step.eid, tries)
                self.log.warning(
                    f"data-flow share {step.eid} (rows {a}-{b}){retry.points(step.items[0][1])}: "
                    f"{sorted(f'{d}@{t}' for d, t, _ in step.blame)} "
                    f"{step.why}; re-sent to {targets} (retry {tries + 1}/{self.retries})")
                self._send_flow_share(names, request, a, b, targets, partials, tries + 1)
        return gave_up
