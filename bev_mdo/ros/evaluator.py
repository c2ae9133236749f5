"""The ROS transport of the engine's Evaluator interface (hub and spoke).

`evaluate(calls)` publishes one EvaluationRequest per (discipline, batch) of a wave,
then spins until every result has arrived. Each request has a fresh evaluation id;
a result is accepted only if run id, evaluation id, discipline and batch shape
match an outstanding request, so a result can never be matched to the wrong
evaluation. Other-run, stale (already answered or unknown id), duplicate (a second
instance answering) and malformed results are dropped and counted. A wave that
times out is re-sent (same evaluation id, attempt + 1) up to `retries` times; then
its points fail (NaN, infeasible) with an error naming the discipline.

With a shared key (``ros.sign_key_file``, see auth.py) every request is signed and
every result verified first; unsigned, forged, expired and replayed results are
dropped and counted under those names. Every accepted result is logged in
``accepted`` as (evaluation id, discipline, instance, attempt sent so far), so a test
can check that each evaluation id was accepted once, from its own discipline.
"""
from __future__ import annotations

import time
import uuid
from collections import Counter
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from bev_mdo.mdo.discipline import EvalResult
from bev_mdo.mdo.evaluator import DisciplineSpec
from bev_mdo.ros import wire
from bev_mdo.ros.auth import Signer
from bev_mdo.ros.fastwait import SubscriptionWaiter
from bev_mdo.ros.common import INFO_QOS, INFO_TOPIC, REQUEST_QOS, RESULT_QOS, RESULT_TOPIC, request_topic, stamp
from bev_mdo_msgs.msg import DisciplineInfo, EvaluationRequest, EvaluationResult


class DisciplineMissing(ValueError):
    """A needed discipline did not appear within the discovery wait."""


@dataclass
class _Pending:
    index: int
    discipline: str
    request: EvaluationRequest
    n: int
    sent_ns: int


class RosEvaluator:
    """Evaluator over ROS topics; same interface as the in-process evaluator."""

    def __init__(self, node: Node, *, run_id: str | None = None, timeout_s: float = 5.0, retries: int = 3,
                 signer: Signer | None = None):
        self.node = node
        if signer is None:  # the coordinator node carries the run config; sign if it names a key file
            from bev_mdo.ros.settings import validate_ros

            config = getattr(node, "config", None) or {}
            signer = Signer.from_ros(validate_ros(config.get("ros"))) if config.get("ros") else None
        self.signer = signer
        self.accepted: list[tuple[int, str, str, int]] = []
        self.run_id = run_id or uuid.uuid4().hex[:16]
        self.timeout_s = timeout_s
        self.retries = retries
        self.specs: dict[str, DisciplineSpec] = {}
        self.counts: Counter[str] = Counter()      # points evaluated per discipline
        self.dropped: Counter[str] = Counter()     # other_run / stale / duplicate / malformed / mismatched
        self.retried = 0
        self.last_latency_s = 0.0
        self._next_id = 1
        self._seq = 0
        self._pending: dict[int, _Pending] = {}
        self._answered: set[int] = set()
        self._results: dict[int, EvalResult] = {}
        self._publishers = {}
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        self._result_sub = node.create_subscription(EvaluationResult, RESULT_TOPIC, self._on_result, RESULT_QOS)
        self._info_sub = node.create_subscription(DisciplineInfo, INFO_TOPIC, self._on_info, INFO_QOS)
        self._waiter = SubscriptionWaiter(self._result_sub, node.context)

    # -- discovery -----------------------------------------------------------------
    def _on_info(self, msg: DisciplineInfo) -> None:
        # Parameter defaults live in the node; the engine only needs their names.
        self.specs[msg.discipline] = DisciplineSpec(
            msg.discipline, tuple(msg.inputs), tuple(msg.outputs), dict.fromkeys(msg.parameters, float("nan"))
        )

    def _publisher(self, discipline: str):
        pub = self._publishers.get(discipline)
        if pub is None:
            pub = self.node.create_publisher(EvaluationRequest, request_topic(discipline), REQUEST_QOS)
            self._publishers[discipline] = pub
        return pub

    def wait_for_disciplines(self, names: Sequence[str], wait_s: float, extra_subscribers: int = 0) -> None:
        """Block until every named discipline declared itself and matched our topics.

        Raises DisciplineMissing naming the ones still absent after `wait_s`.
        """
        for n in names:
            self._publisher(n)
        deadline = time.monotonic() + wait_s

        def missing() -> list[str]:
            out = []
            for n in names:
                ready = (
                    n in self.specs
                    and self._publishers[n].get_subscription_count() >= 1 + extra_subscribers
                    and self.node.count_publishers(RESULT_TOPIC) >= 1
                )
                if not ready:
                    out.append(n)
            return out

        while missing():
            if time.monotonic() > deadline:
                raise DisciplineMissing(
                    f"discipline(s) {missing()} not found on ROS domain within {wait_s:g} s "
                    "(is each node running, with the same ROS_DOMAIN_ID and discovery settings?)"
                )
            self._executor.spin_once(timeout_sec=0.05)
        # Our result subscription must be matched to every discipline's publisher too.
        while self._result_sub.get_publisher_count() < len(set(names)):
            if time.monotonic() > deadline:
                raise DisciplineMissing(f"result topic not matched for all of {list(names)} within {wait_s:g} s")
            self._executor.spin_once(timeout_sec=0.05)

    # -- evaluation ----------------------------------------------------------------
    def _on_result(self, msg: EvaluationResult) -> None:
        if self.signer is not None:
            why = self.signer.verify_result(msg)
            if why is not None:
                self.dropped[why] += 1
                return
        if msg.run_id != self.run_id:
            self.dropped["other_run"] += 1
            return
        p = self._pending.get(msg.evaluation_id)
        if p is None:
            self.dropped["duplicate" if msg.evaluation_id in self._answered else "stale"] += 1
            return
        if msg.discipline != p.discipline:
            self.dropped["mismatched"] += 1
            return
        if msg.status == EvaluationResult.STATUS_REJECTED:
            res = self._failed(p, msg.error or f"{p.discipline}: request rejected")
        else:
            try:
                outputs = wire.from_named_array(msg.outputs)
            except wire.WireError:
                self.dropped["malformed"] += 1
                return
            spec = self.specs.get(p.discipline)
            want = spec.outputs if spec else tuple(outputs)
            ok = np.asarray(msg.point_ok, dtype=bool)
            if any(k not in outputs for k in want) or int(msg.outputs.batch_size) != p.n or ok.shape != (p.n,):
                self.dropped["malformed"] += 1
                return
            outs = {k: np.array(outputs[k]) for k in want}
            ok = ok & np.all([np.isfinite(v) for v in outs.values()], axis=0) if outs else ok
            res = EvalResult(outs, ok, msg.error, float(msg.compute_time_s))
        self.counts[p.discipline] += p.n
        self.accepted.append((int(msg.evaluation_id), msg.discipline, msg.instance, int(p.request.attempt)))
        del self._pending[msg.evaluation_id]
        self._answered.add(msg.evaluation_id)
        self._results[p.index] = res

    def _failed(self, p: _Pending, error: str) -> EvalResult:
        spec = self.specs.get(p.discipline)
        outs = {k: np.full(p.n, np.nan) for k in (spec.outputs if spec else ())}
        return EvalResult(outs, np.zeros(p.n, bool), error)

    def _send(self, p: _Pending) -> None:
        self._seq += 1
        p.request.sequence = self._seq
        stamp(p.request.header)  # a retry gets a fresh stamp (and signature): it is not a replay
        if self.signer is not None:
            self.signer.sign_request(p.request)
        p.sent_ns = time.monotonic_ns()
        self._publisher(p.discipline).publish(p.request)

    def evaluate(self, calls: Sequence[tuple[str, Mapping[str, np.ndarray]]], iteration: int = 0) -> list[EvalResult]:
        """Evaluate one wave: every (discipline, batch) call concurrently. Never raises for a slow node."""
        t0 = time.perf_counter()
        self._results = {}
        for i, (name, batch) in enumerate(calls):
            req = EvaluationRequest()
            req.run_id = self.run_id
            req.evaluation_id = self._next_id
            req.iteration = iteration
            req.discipline = name
            wire.to_named_array(batch, req.inputs)
            n = int(req.inputs.batch_size)
            self._pending[self._next_id] = p = _Pending(i, name, req, n, 0)
            self._next_id += 1
            self._send(p)
        for attempt in range(self.retries + 1):
            deadline = time.monotonic() + self.timeout_s
            self._waiter.take_all(self._on_result)
            while self._pending and time.monotonic() < deadline:
                self._waiter.wait(deadline - time.monotonic())
                self._waiter.take_all(self._on_result)
            if not self._pending:
                break
            if attempt < self.retries:
                for p in self._pending.values():
                    self.retried += 1
                    p.request.attempt = attempt + 1
                    self.node.get_logger().warning(
                        f"no answer from {p.discipline!r} for evaluation {p.request.evaluation_id} "
                        f"after {self.timeout_s:g} s; retry {attempt + 1}/{self.retries}"
                    )
                    self._send(p)
        for eid, p in list(self._pending.items()):
            self._results[p.index] = self._failed(
                p, f"{p.discipline}: no answer after {self.retries + 1} attempts of {self.timeout_s:g} s"
            )
            del self._pending[eid]
            self._answered.add(eid)  # a late answer is then counted as stale, never used
        self.last_latency_s = time.perf_counter() - t0
        return [self._results[i] for i in range(len(calls))]

    def close(self) -> None:
        """Release the executor (the node is the caller's)."""
        self._executor.remove_node(self.node)
        self._executor.shutdown()
