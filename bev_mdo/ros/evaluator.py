"""The ROS transport of the engine's Evaluator interface (hub and spoke).

`evaluate(calls)` publishes one EvaluationRequest per (discipline, batch) of a wave,
then spins until every result has arrived. Each request has a fresh evaluation id;
a result is accepted only if run id, evaluation id, discipline and batch shape
match an outstanding request, so a result can never be matched to the wrong
evaluation. Other-run, stale (already answered or unknown id), duplicate (a second
instance answering) and malformed results are dropped and counted. A wave that
times out is re-sent (same evaluation id, attempt + 1) up to `retries` times; then
its points fail (NaN, infeasible) with an error naming the discipline.

Data flow (``evaluate_flow``, mdo/flow.py): a feed-forward MDA is ONE request on
/bev_mdo/mda_request naming the disciplines, read by those without sources; every result
(/bev_mdo/<discipline>/mda_result) forwards the request's columns, so a consumer needs only
its sources' results, and the coordinator collects every discipline's result there. It is used only when every node declared (DisciplineInfo) that it reads each coupling
input from the same producer as the coordinator's graph; otherwise the MDA runs in waves.
With worker pools the MDA is cut into row shares, one data-flow request each, every pooled
discipline addressed to one of its instances (``_flow_shares``; docs/scaling.md).

With a shared key (``ros.sign_key_file``, see protocol/signing.py) every request is signed and
every result verified first; unsigned, forged, expired and replayed results are
dropped and counted under those names. Every accepted result is logged in
``accepted`` as (evaluation id, discipline, instance, attempt sent so far), so a test
can check that each evaluation id was accepted once, from its own discipline.
"""
from __future__ import annotations

import functools
import sys
import time
import uuid
from collections import Counter
from typing import Mapping, Sequence

import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from bev_mdo.mdo import flow, retry
from bev_mdo.mdo.discipline import EvalResult, all_finite, failed, finite_rows
from bev_mdo.mdo.evaluator import DisciplineSpec
from bev_mdo.mdo.graph import CouplingGraph
from bev_mdo.mdo.ledger import Ledger
from bev_mdo import protocol
from bev_mdo.ros import binding, pool as pools
from bev_mdo.ros_settings import validate_min_rows
from bev_mdo.protocol.signing import Signer
from bev_mdo.ros.fastwait import STARTUP_CAP, MultiWaiter, until
from bev_mdo.stacks import StartupGaveUp
from bev_mdo.ros.common import (INFO_QOS, INFO_TOPIC, MDA_REQUEST_TOPIC, REQUEST_QOS, RESULT_QOS, RESULT_TOPIC,
                                mda_result_topic, request_topic, stamp)
from bev_mdo_msgs.msg import DisciplineInfo, EvaluationRequest, EvaluationResult


# A data-flow share has at least this many rows. Every discipline of the MDA computes each share
# on its own, and numpy reduces a batch of ONE row in another order than a batch of several (a
# contiguous axis is summed pairwise): the acceleration model differs in the last bit between
# n = 1 and n > 1. Shares of two rows or more keep the joined result bitwise the single-request one.
FLOW_MIN_ROWS = 2

_STATUS_REJECTED = EvaluationResult.STATUS_REJECTED  # read once: a metaclass property call each time


class DisciplineMissing(StartupGaveUp):
    """A needed discipline did not appear, match or answer within the discovery wait."""


_Pending = retry.Sent  # an outstanding answer (mdo/retry.py); the name tests and composed.py use


class RosEvaluator:
    """Evaluator over ROS topics; same interface as the in-process evaluator."""

    def __init__(self, node: Node, *, run_id: str | None = None, timeout_s: float = 5.0, retries: int = 3,
                 signer: Signer | None = None, config: Mapping | None = None):
        self.node = node
        if config:  # the run's config, parsed once (config.RunConfig)
            from bev_mdo.config import RunConfig

            config = RunConfig.of(config)
        ros = config.ros if config else {}
        if signer is None:  # sign if the run config names a key file
            signer = Signer.from_ros(ros) if config else None
        self.signer = signer
        # Binding (binding.py): the fingerprint every discipline of this run must have. Without a
        # config (a bare evaluator in a tool) the first declared fingerprint of a discipline is taken.
        self._config = config or None
        self.expected: dict[str, tuple[str, str]] = {}   # discipline -> (fingerprint, effective JSON)
        self._tags: dict[tuple, str] = {}                # names -> their request frame_id (_tag)
        self.instances: dict[str, set[str]] = {}         # discipline -> accepted instance names
        self.refused: dict[str, str] = {}                # "discipline instance" -> why it was refused
        self.first_errors: dict[str, str] = {}           # discipline -> its first error (shown once)
        self.accepted: list[tuple[int, str, str, int]] = []
        self.run_id = run_id or uuid.uuid4().hex[:16]
        self.timeout_s = timeout_s
        self.retries = retries
        self.specs: dict[str, DisciplineSpec] = {}
        self.counts: Counter[str] = Counter()      # points evaluated per discipline
        # ids, outstanding/answered/reassigned requests and why answers were dropped (mdo/ledger.py)
        self.ledger: Ledger[_Pending] = Ledger(lambda p: p.request.header.frame_id)
        self.dropped: Counter[str] = self.ledger.dropped  # other_run / stale / duplicate / malformed / ...
        self.retried = 0
        # the optimiser iteration the requests belong to: how many iteration records were published
        # before them (0: the start point); the coordinator moves it on after each record
        self.iteration = 0
        self.unresponsive: set[str] = set()  # disciplines that let every attempt of a request time out
        self.last_latency_s = 0.0
        self._seq = 0
        self._pending = self.ledger.pending   # (evaluation id, discipline) -> request
        self._results: dict[int, EvalResult] = {}
        self._publishers = {}
        self.coupling_sources: dict[str, dict[str, str]] = {}  # discipline -> {coupling input: source}
        self.flows = 0  # MDAs served by data flow (one request each)
        self._flow_plans: dict[tuple, dict | None] = {}
        self._flow_pub = None
        self._flow_subs: dict[str, object] = {}
        # Worker pools (pool.py): several accepted instances of a discipline share each batch.
        self.pool_mode = pools.validate_mode(ros.get("pool", "share"))
        self.pools: dict[str, pools.Pool] = {}
        self._shares = retry.Shares()                       # answers of row shares, joined in row order
        self._batches: dict[int, tuple[str, Mapping]] = {}  # wave index -> (discipline, batch) of a pool's call
        self.flow_shares = 0  # data-flow requests sent as row shares of pooled MDAs
        # False: an MDA with a pool runs in waves (only the pooled disciplines see shares; the
        # others get the whole batch once), as before data flow with pools (docs/scaling.md)
        self.pool_data_flow = ros.get("pool_data_flow", True) is not False
        self.pool_min_rows = validate_min_rows(ros.get("pool_min_rows", 1))
        self._info_t = time.monotonic()
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        # Raw CDR in and out (the protocol's generated codec): rclpy's message objects cost more than the DDS hop.
        self._result_sub = node.create_subscription(EvaluationResult, RESULT_TOPIC, self._on_bytes, RESULT_QOS,
                                                    raw=True)
        # raw too: a signature covers the bytes as they were sent (protocol/signing.py)
        self._info_sub = node.create_subscription(DisciplineInfo, INFO_TOPIC, self._on_info, INFO_QOS, raw=True)
        self._waiter = MultiWaiter(node.context)
        self._hot = [(self._result_sub, lambda data, _i: self._on_bytes(data))]
        self.local_requests = None  # composed.Beside: (publisher, request) -> True if delivered in process
        self.starting = None  # start-up progress of the run's own processes (launch.Launcher.progress)

    @property
    def policy(self) -> retry.Policy:
        """When a request is late and how often it is re-sent (mdo/retry.py)."""
        return retry.Policy(self.timeout_s, self.retries)

    @property
    def request_publishers(self) -> list:
        """Every request publisher this evaluator made (one per discipline, and the data-flow one)."""
        return list(self._publishers.values())

    @property
    def probe_late(self) -> int:
        """Late answers to readiness probes (ignored, not drops)."""
        return self.ledger.probe_late

    @property
    def _next_id(self) -> int:  # the evaluation id the next request gets
        return self.ledger.next_id

    # -- discovery -----------------------------------------------------------------
    def _expect(self, name: str) -> tuple[str, str] | None:
        """(fingerprint, effective JSON) this run needs for discipline `name` (None: not known)."""
        if name not in self.expected and self._config is not None:
            try:
                self.expected[name] = binding.fingerprint(self._config, name)
            except ValueError:
                return None
        return self.expected.get(name)

    def _refuse(self, msg: DisciplineInfo, why: str) -> None:
        key = f"{msg.discipline} {msg.instance}"
        if key not in self.refused:
            self.refused[key] = why
            self.dropped["refused_instance"] += 1
            self.node.get_logger().warning(f"refused {msg.discipline!r} instance {msg.instance!r}: {why}")

    def _on_info(self, data: bytes) -> None:
        """A discipline's declaration (its CDR bytes): accept the instance, or refuse it by name."""
        try:
            msg = deserialize_message(data, DisciplineInfo)
        except Exception:  # noqa: BLE001 - rclpy raises several types for bytes that are not one
            self.dropped["info_malformed"] += 1
            return None
        if not binding.run_matches(msg.run_id, self.run_id):
            # a node launched for another run (another job on this domain, signed with that run's key):
            # not ours, and not a forgery either; ignoring it needs no trust in its claim
            self.dropped["info_other_run"] += 1
            return None
        if self.signer is not None:
            why = self.signer.verify_info(data)
            if why is not None:
                self.dropped[f"info_{why}"] += 1
                return self._refuse(msg, f"{why} declaration")
        if binding.fingerprint_of_json(msg.effective_config) != msg.fingerprint:
            return self._refuse(msg, "fingerprint does not match its effective configuration")
        want = self._expect(msg.discipline)
        if want is None and self._config is None:
            want = self.expected[msg.discipline] = (msg.fingerprint, msg.effective_config)
        if want is None:
            self.dropped["info_other_discipline"] += 1
            return None  # a discipline this run does not use
        if msg.fingerprint != want[0]:
            return self._refuse(msg, f"fingerprint {msg.fingerprint} != {want[0]}: "
                                     + binding.difference(want[1], msg.effective_config))
        self.refused.pop(f"{msg.discipline} {msg.instance}", None)
        self.instances.setdefault(msg.discipline, set()).add(msg.instance.lstrip("/"))
        self._pool(msg.discipline).revive(msg.instance.lstrip("/"))
        # Parameter defaults live in the node; the engine only needs their names.
        self.specs[msg.discipline] = DisciplineSpec(
            msg.discipline, tuple(msg.inputs), tuple(msg.outputs), dict.fromkeys(msg.parameters, float("nan"))
        )
        self.coupling_sources[msg.discipline] = dict(zip(msg.coupling_inputs, msg.coupling_sources))
        self._flow_plans.clear()

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
                # with pools (share mode) a data-flow MDA is split into row shares (_flow_shares)
            self._flow_plans[key] = plan
        return self._flow_plans[key]

    def flow_readers(self) -> dict[str, int]:
        """Data-flow result topic -> how many readers it has without recorders (the coordinator and
        the disciplines reading it), for the data flow set up by ``wait_for_disciplines``."""
        out = {}
        for d in self._flow_subs:
            out[mda_result_topic(d)] = 1 + sum(d in src.values() for src in self.coupling_sources.values())
        return out

    def _flow_topics(self, names: Sequence[str]) -> None:
        if self._flow_pub is None:
            self._flow_pub = self.node.create_publisher(EvaluationRequest, MDA_REQUEST_TOPIC, REQUEST_QOS)
            self._publishers[MDA_REQUEST_TOPIC] = self._flow_pub
        for n in names:
            if n not in self._flow_subs:
                # VOLATILE reader: the coordinator wants only the answers to what it sends.
                sub = self.node.create_subscription(EvaluationResult, mda_result_topic(n), self._on_bytes, RESULT_QOS,
                                                    raw=True)
                self._flow_subs[n] = sub
                self._hot.append((sub, lambda data, _i: self._on_bytes(data)))

    def _publisher(self, discipline: str):
        pub = self._publishers.get(discipline)
        if pub is None:
            pub = self.node.create_publisher(EvaluationRequest, request_topic(discipline), REQUEST_QOS)
            self._publishers[discipline] = pub
        return pub

    def progress(self, names: Sequence[str] = ()) -> tuple:
        """What start-up progress is measured by (fastwait.until): the nodes on the graph, the
        declarations taken, the matches of our request and result topics and, with ``starting``
        (launch.Launcher.progress), the CPU time of the run's processes not yet on the graph."""
        pubs = self._publishers
        return (self.starting() if self.starting is not None else (), tuple(sorted(self.node.get_node_names())), tuple(sorted(self.specs)), len(self.refused),
                sum(len(v) for v in self.instances.values()), self._result_sub.get_publisher_count(),
                tuple(p.get_subscription_count() for p in pubs.values()),
                tuple(s.get_publisher_count() for s in self._flow_subs.values()))

    def wait_for_disciplines(self, names: Sequence[str], wait_s: float, extra_subscribers: int = 0) -> None:
        """Block until every named discipline declared itself and matched our topics, then prove
        every path delivers (handshake). Waits as long as discovery makes progress (fastwait.until):
        raises DisciplineMissing naming the ones still absent once nothing changed for `wait_s`.
        `extra_subscribers`: readers of each request topic to wait for besides the discipline's (the
        run's recorder is waited for by name instead: coordinator_node.wait_for_recorder)."""
        for n in names:
            self._publisher(n)

        def missing() -> list[str]:
            out = []
            for n in names:
                ready = (
                    n in self.specs
                    and self._publishers[n].get_subscription_count() >= 1 + extra_subscribers
                    and self.node.count_publishers(RESULT_TOPIC) >= 1
                    and self._present(n, request_topic(n), subscriber=True)
                    # every reader in the graph matched: with other instances (another run's, a
                    # refused one, a recorder) on the topic, a count alone could be reached without ours
                    and self._publishers[n].get_subscription_count() >= self.node.count_subscribers(request_topic(n))
                    and self._present(n, RESULT_TOPIC, subscriber=False)
                )
                if not ready:
                    out.append(n)
            return out

        spin = functools.partial(self._executor.spin_once, timeout_sec=0.05)
        progress = functools.partial(self.progress, names)
        if not until(lambda: not missing(), wait_s, spin, progress,
                     lambda: f"discipline(s) {missing()} ({len(self.specs)} of {len(names)} declared)"):
            gone = missing()
            if gone:
                refused = [f"{k}: {why}" for k, why in self.refused.items() if k.split(" ")[0] in gone]
                if refused:
                    raise DisciplineMissing(f"discipline(s) {gone}: no instance of this run's configuration "
                                            f"(nothing changed for {wait_s:g} s); refused " + " | ".join(refused))
                raise DisciplineMissing(
                    f"discipline(s) {gone} not found on ROS domain: discovery made no progress for {wait_s:g} s "
                    "(is each node running, with the same ROS_DOMAIN_ID and discovery settings? see its log in "
                    "the run's logs folder; LOCALHOST discovery reaches about 32 processes per domain, "
                    "docs/scaling.md; ros.discovery_wait_s sets this bound)"
                )
        # Our result subscription must be matched to every discipline's publisher too.
        if not until(lambda: self._result_sub.get_publisher_count() >= len(set(names)), wait_s, spin, progress,
                     "the result topic to match every discipline"):
            raise DisciplineMissing(f"result topic not matched for all of {list(names)}: no progress for {wait_s:g} s")
        # Declarations that arrived with ours (other instances on the domain) are judged now: once
        # the run evaluates, only the hot subscriptions are served.
        for _ in range(16):
            self._executor.spin_once(timeout_sec=0.0)
        flow_ok = self.flow_plan(names) is not None
        if not flow_ok:
            self.node.get_logger().info("data flow not used (a node does not offer it, or the graph has a loop): "
                                        "MDAs run in waves")
        else:
            # Data flow: the disciplines without sources read the MDA request topic and we read every
            # node's results. (Node-to-node result topics are TRANSIENT_LOCAL: a late match loses nothing.)
            self._flow_topics(names)
            roots = {n for n, src in self.flow_plan(names).items() if not src}
            if not until(lambda: (self._flow_pub.get_subscription_count()
                                  >= max(len(roots), self.node.count_subscribers(MDA_REQUEST_TOPIC))
                                  and all(self._flow_subs[n].get_publisher_count() >= 1 for n in names)
                                  and all(self._present(n, MDA_REQUEST_TOPIC, subscriber=True) for n in roots)
                                  and all(self._present(n, mda_result_topic(n), subscriber=False) for n in names)),
                         wait_s, spin, progress, "the data-flow topics to match"):
                raise DisciplineMissing(f"data-flow topics not matched for all of {list(names)}: no progress "
                                        f"for {wait_s:g} s")
        self.handshake(names, wait_s, flow_ok)

    def handshake(self, names: Sequence[str], wait_s: float = 20.0, data_flow: bool | None = None) -> None:
        """Prove that every path a run uses delivers, before the first real request.

        The graph counts above are what THIS process sees: our reader knowing a node's result
        writer does not mean that writer knows our reader yet (each side matches the other on
        its own discovery traffic), and a VOLATILE result published before the writer matched us
        is lost, not late (the lost first request seen as ``no answer from ['cost'] for evaluation
        1 after 5 s; retry 1/3`` on a loaded host). So every discipline answers one request of no
        point (hub and spoke) and, when the MDA uses data flow, one empty data-flow MDA, re-sent
        with a fresh evaluation id every 0.1-1 s until answered: a round trip shows both ends of
        every topic matched. Nothing is evaluated or counted; a late answer to an earlier probe is
        ignored (``probe_late``). It waits as long as something progresses (a probe answered, the
        graph changed) and raises DisciplineMissing naming a discipline that did not answer once
        nothing changed for `wait_s`."""
        names = list(dict.fromkeys(names))
        if data_flow is None:
            data_flow = self.flow_plan(names) is not None and all(n in self._flow_subs for n in names)
        kept = len(self.accepted)
        start, last, state, shown = time.monotonic(), time.monotonic(), self.progress(names), time.monotonic()
        rounds = [("request", n) for n in names] + ([("flow", None)] if data_flow else [])
        for kind, name in rounds:
            interval = 0.1
            while True:
                eid = self.ledger.new_id(probe=True)
                if kind == "request":
                    req = self._request(eid, name, {k: np.zeros(0) for k in self.specs[name].inputs},
                                        self._tag([name]), iteration=0)
                    keys = [(eid, name)]
                    self._pending[keys[0]] = p = _Pending(0, name, req, 0, 0)
                else:
                    req = self._request(eid, "", {}, self._tag(names), flow=names, iteration=0)
                    keys = [(eid, n) for n in names]
                    for i, n in enumerate(names):
                        self._pending[(eid, n)] = _Pending(i, n, req, 0, 0, flow=True)
                    p = self._pending[keys[0]]  # one message for every discipline
                self._send(p)
                self._wait_pending(interval)
                late = [k[1] for k in keys if k in self._pending]
                for k in keys:
                    self._pending.pop(k, None)
                now = time.monotonic()
                if not late:
                    last = now  # an answer is progress
                    break
                if (s := self.progress(names)) != state:
                    state, last = s, now
                if now - last >= wait_s or now - start > STARTUP_CAP * wait_s:  # as fastwait.until
                    why = f"nothing changed for {wait_s:g} s" if now - last >= wait_s else f"{now - start:.0f} s in all"
                    raise DisciplineMissing(f"discipline(s) {late} are matched but did not answer a probe "
                                            f"({'data flow' if kind == 'flow' else 'request'}); {why}")
                if now - shown >= 2.0:
                    shown = now
                    print(f"[start-up] waiting for {late} to answer a probe; gives up in "
                          f"{wait_s - (now - last):.0f} s without progress", file=sys.stderr, flush=True)
                interval = min(2 * interval, 1.0)
        del self.accepted[kept:]
        self._results = {}

    def _wait_pending(self, seconds: float) -> None:
        """Take results until nothing is pending or `seconds` passed (no re-send)."""
        self._take_until(time.monotonic() + seconds)

    def _present(self, discipline: str, topic: str, subscriber: bool) -> bool:
        """True once an accepted instance of `discipline` is in the graph as a subscriber (publisher)
        of `topic`: a refused instance on the same topic does not make this run ready."""
        accepted = self.instances.get(discipline, set())
        infos = (self.node.get_subscriptions_info_by_topic(topic) if subscriber
                 else self.node.get_publishers_info_by_topic(topic))
        for i in infos:
            full = f"{i.node_namespace.rstrip('/')}/{i.node_name}".lstrip("/")
            if full in accepted or i.node_name in accepted:
                return True
        return False

    def warm_up(self, names: Sequence[str], rounds: int = 2) -> None:
        """Send `rounds` MDAs of no point through the matched graph, before any timing (call it
        after every start-up wait, the recorder's included, so a recording has all of it).

        The first samples between a new writer and its readers cost more than the later ones
        (measured: the first MDA of a run took 3.9-4.2 ms against 2.6-2.8 ms for the rest; after
        one empty MDA 3.2-3.7 ms, after two 2.8-2.9 ms). The first round is the handshake (every
        path, with short re-sends: nothing is lost to a late match); the others go the way the MDA
        goes: one data-flow MDA for a feed-forward graph, else one wave of empty requests (a loop
        is iterated hub and spoke; data flow cannot start a loop, so it is never tried there).
        An empty MDA evaluates nothing, so the evaluation counts do not change; its results are
        not kept in ``accepted`` or ``flows``. A recorder sees its requests and results."""
        kept, flows = len(self.accepted), self.flows
        names = list(names)
        self.handshake(names)
        for _ in range(rounds - 1):
            if self.evaluate_flow(names, {}, 0) is None:
                self.evaluate([(n, {k: np.zeros(0) for k in self.specs[n].inputs}) for n in names])
        del self.accepted[kept:]
        self.flows = flows

    # -- evaluation ----------------------------------------------------------------
    def _on_bytes(self, data: bytes) -> None:
        try:
            msg = protocol.decode_result(data)
        except protocol.WireError:
            self.dropped["malformed"] += 1
            return
        self._on_result(msg)

    def _on_result(self, msg) -> None:
        """Accept a received result (protocol.EvaluationResult or a generated EvaluationResult), every field
        checked (signature, ledger, shapes, finiteness, point errors), or count why it was dropped."""
        if msg.run_id != self.run_id:  # another run's traffic on the shared topic, not an attack
            self.dropped["other_run"] += 1
            return
        if self.signer is not None:
            why = self.signer.verify_result(msg)
            if why is not None:
                self.dropped[why] += 1
                return
        key = (int(msg.evaluation_id), msg.discipline)
        p = self.ledger.match(*key, msg.header.frame_id)  # None: why is counted (fingerprint, stale, ...)
        if p is None:
            return
        if msg.status == _STATUS_REJECTED:
            res = self._failed(p, msg.error or f"{p.discipline}: request rejected")
        else:
            try:
                outputs = protocol.from_named_array(msg.outputs)
            except protocol.WireError:
                self.dropped["malformed"] += 1
                return
            spec = self.specs.get(p.discipline)
            want = spec.outputs if spec else tuple(outputs)
            ok = np.asarray(msg.point_ok, dtype=bool)
            if any(k not in outputs for k in want) or int(msg.outputs.batch_size) != p.n or ok.shape != (p.n,):
                self.dropped["malformed"] += 1
                return
            outs = {k: np.array(outputs[k]) for k in want}
            ok = np.array(ok) if all_finite(outs.values()) else ok & finite_rows(list(outs.values()), p.n)
            try:
                why = protocol.point_errors_of(msg, p.n)
            except protocol.WireError:
                self.dropped["malformed"] += 1
                return
            res = EvalResult(outs, ok, msg.error, float(msg.compute_time_s), point_errors=why)
            if p.request.partials:
                try:
                    part = protocol.partials_of(msg.partials, p.n)
                except protocol.WireError:
                    self.dropped["malformed"] += 1
                    return
                if part is not None:
                    res.extra["partials"] = {k: np.array(v) for k, v in part.items()}
        self._accept(key, p, res, msg.instance)

    def on_local(self, req, discipline: str, instance: str, res: EvalResult | None, error: str = "") -> None:
        """A result handed over by a node composed into this process (composed.Beside), never a
        message: the node's own `run_discipline` result (``res``; None: the node rejected the
        request, ``error`` says why) for ``req``, the request (or a data-flow source's result) it
        answers. Nothing outside the process can make this call, so only what concerns
        correctness is checked: run id, and the ledger's match of evaluation id, discipline and
        binding (stale, duplicate, mismatched are counted as for a received result); the result
        was checked once, by run_discipline, and is taken as the in-process evaluator takes it."""
        if req.run_id != self.run_id:
            self.dropped["other_run"] += 1
            return
        key = (int(req.evaluation_id), discipline)
        p = self.ledger.match(*key, req.header.frame_id)
        if p is None:
            return
        if res is None:
            res = self._failed(p, error or f"{discipline}: request rejected")
        elif np.shape(res.ok) != (p.n,):  # a node's answer to other rows than the ledger's (a bug)
            self.dropped["malformed"] += 1
            return
        self._accept(key, p, res, instance)

    def _accept(self, key: tuple[int, str], p: _Pending, res: EvalResult, instance: str) -> None:
        """Take `res` as the answer of the ledger entry `p` (`key`): counted, logged in `accepted`."""
        if res.error:
            self._first_error(p.discipline, res.error)
        if not p.flow:  # a data-flow MDA counts the rows each discipline evaluated at the end
            self.counts[p.discipline] += p.n
        self.accepted.append((key[0], key[1], instance, int(p.request.attempt)))
        self.ledger.settle(*key)
        if p.target:
            self._pool(p.discipline).record(p.target, p.n, (time.monotonic_ns() - p.sent_ns) * 1e-9)
        if p.start >= 0:  # a row share (of a pool's call, or of a data-flow MDA: _flow_shares)
            self._shares.add(key[0], p.index, p.start, res)
        else:
            self._results[p.index] = res

    def _first_error(self, discipline: str, error: str) -> None:
        """Name a discipline's first failure on the console (the node's log has the rest)."""
        if discipline not in self.first_errors:
            self.first_errors[discipline] = line = error.strip().splitlines()[0][:300]
            self.node.get_logger().error(f"discipline {discipline!r} failed: {line}")

    def _failed(self, p: _Pending, error: str) -> EvalResult:
        spec = self.specs.get(p.discipline)
        return failed(spec.outputs if spec else (), p.n, error)

    def _tag(self, names) -> str:
        """frame_id binding a request to this run's fingerprint of every named discipline."""
        key = tuple(names)
        tag = self._tags.get(key)
        if tag is None:
            fps = {n: (self._expect(n) or ("?", ""))[0] for n in names}
            tag = binding.tag(fps, names)
            if "?" not in fps.values():  # kept once every fingerprint is known (they do not change)
                self._tags[key] = tag
        return tag

    def _request(self, eid: int, discipline: str, batch: Mapping[str, np.ndarray], tag: str, *,
                 flow: Sequence[str] = (), iteration: int | None = None, attempt: int = 0,
                 partials: bool = False) -> protocol.EvaluationRequest:
        """A request of this run carrying `batch`, bound by `tag` (its frame_id: binding.py);
        `discipline` empty and `flow` the MDA's disciplines for a data-flow request."""
        req = protocol.request(self.run_id, eid, discipline, flow=flow,
                           iteration=self.iteration if iteration is None else iteration)
        req.header.frame_id = tag
        req.attempt = attempt
        req.inputs = protocol.batch(batch)
        req.partials = bool(partials)
        return req

    def _send(self, p: _Pending) -> None:
        self._seq += 1
        p.request.sequence = self._seq
        stamp(p.request.header)  # a retry gets a fresh stamp (and signature): it is not a replay
        p.sent_ns = time.monotonic_ns()
        pub = self._flow_pub if p.flow else self._publisher(p.discipline)
        # nodes composed into this process (composed.Beside) take it by direct call when nobody else
        # reads it: not encoded and not signed (it never leaves the process)
        if self.local_requests is None or not self.local_requests(pub, p.request):
            pub.publish(protocol.encode_request(p.request) if self.signer is None
                        else self.signer.sign_request(p.request))  # sets its signature

    def evaluate(self, calls: Sequence[tuple[str, Mapping[str, np.ndarray]]], iteration: int | None = None,
                 partials: bool = False) -> list[EvalResult]:
        """Evaluate one wave: every (discipline, batch) call concurrently. Never raises for a slow node.
        With ``partials`` the nodes return their disciplines' analytic partials too."""
        t0 = time.perf_counter()
        iteration = self.iteration if iteration is None else int(iteration)
        self._results = {}
        self._shares, self._batches = retry.Shares(), {}
        self._poll_info()
        shared = False
        for i, (name, batch) in enumerate(calls):
            if name in self.unresponsive:
                n = len(next(iter(batch.values()), ()))
                self._results[i] = self._failed(_Pending(i, name, None, n, 0),
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
            p = self.ledger.open(self.ledger.new_id(), name, _Pending(i, name, req, n, 0))
            self._send(p)
        if shared:
            self._await_pool(iteration)
            for i in self._shares.indices():  # every pooled call's shares, joined in row order
                spec = self.specs.get(calls[i][0])
                self._results[i] = self._shares.join(i, spec.outputs if spec else None)
        else:
            self._await()
        self.last_latency_s = time.perf_counter() - t0
        return [self._results[i] for i in range(len(calls))]

    def evaluate_flow(self, names: Sequence[str], request: Mapping[str, np.ndarray], n: int,
                      partials: bool = False) -> dict | None:
        """One feed-forward MDA as ONE data-flow request; None when the nodes cannot serve it that way."""
        plan = self.flow_plan(names)
        if plan is None or self.unresponsive.intersection(names):
            return None
        t0 = time.perf_counter()
        self._flow_topics(names)
        self._results = {}
        self._poll_info()
        pooled = {d: live for d in names if (live := self._live(d) if n > 0 else None) and len(live) > 1}
        if pooled:
            if not self.pool_data_flow:
                return None
            return self._flow_shares(names, plan, request, n, bool(partials), pooled, t0)
        eid = self.ledger.new_id()
        req = self._request(eid, "", request, self._tag(names), flow=names, partials=partials)
        first = None
        for i, name in enumerate(names):
            p = self.ledger.open(eid, name, _Pending(i, name, req, n, 0, flow=True))
            first = first or p
        self._send(first)  # one message for every discipline
        self._await()
        self.flows += 1
        out = {name: self._results[i] for i, name in enumerate(names)}
        answered = {d for e, d, _, _ in self.accepted[-len(names):] if e == eid}
        self.counts.update(flow.rows_per_discipline(plan, out, n, [d for d in names if d in answered]))
        self.last_latency_s = time.perf_counter() - t0
        return out

    # -- data flow with pools ------------------------------------------------------
    def _flow_shares(self, names: Sequence[str], plan: Mapping[str, Mapping[str, str]],
                     request: Mapping[str, np.ndarray], n: int, partials: bool,
                     pooled: Mapping[str, list[str]], t0: float) -> dict:
        """One data-flow MDA over pools: its rows are cut into shares (in proportion to the
        throughput of the largest pool's instances), and each share is ONE data-flow request in
        which every pooled discipline is addressed to one of its instances (the largest pool: one
        instance per share; a smaller pool: its instances in turn). So each instance evaluates
        its own rows, a consumer joins its sources' results of the same share as without pools,
        and the coordinator joins every discipline's shares in row order. A share not answered
        within the timeout, or whose instance left the graph, is re-sent whole (new evaluation id,
        other instances) and its old answers are dropped (``late_share``; mdo/retry.py decides)."""
        lead = max(pooled, key=lambda d: (len(pooled[d]), d))
        self._shares = retry.Shares()
        for j, (inst, a, b) in enumerate(self._pool(lead).split(
                n, pooled[lead], min_rows=max(FLOW_MIN_ROWS, pools.min_rows_of(self.pool_min_rows, lead)))):
            targets = {d: inst if d == lead else live[j % len(live)] for d, live in pooled.items()}
            self._send_flow_share(names, request, a, b, targets, partials, 0)
        gave_up = self._await_flow_shares(names, plan, request, partials)
        out = {}
        for i, name in enumerate(names):
            spec = self.specs.get(name)
            out[name] = self._shares.join(i, spec.outputs if spec else None)
        self.flows += 1
        self.counts.update(flow.rows_per_discipline(plan, out, n, [d for d in names if d not in gave_up]))
        self._shares = retry.Shares()
        self.last_latency_s = time.perf_counter() - t0
        return out

    def _send_flow_share(self, names: Sequence[str], request: Mapping[str, np.ndarray], a: int, b: int,
                         targets: Mapping[str, str], partials: bool, tries: int) -> None:
        eid = self.ledger.new_id()
        fps = {d: (self._expect(d) or ("?", ""))[0] for d in names}
        tag = binding.tag({d: f"{fp}{binding.TARGET_SEP}{targets[d]}" if d in targets else fp
                           for d, fp in fps.items()}, names)
        req = self._request(eid, "", {k: np.asarray(v)[a:b] for k, v in request.items()}, tag, flow=names,
                            attempt=tries, partials=partials)
        sent = [self.ledger.open(eid, name, _Pending(i, name, req, b - a, 0, flow=True, target=targets.get(name, ""),
                                                     start=a, tries=tries)) for i, name in enumerate(names)]
        self._shares.sent(eid, a, b, tries)
        self.flow_shares += 1
        self._send(sent[0])  # one message for every discipline of the share
        for p in sent[1:]:
            p.sent_ns = sent[0].sent_ns

    def _wait_shares(self, checked: float, check_s: float) -> tuple[int, set[tuple[str, str]], float]:
        """Wait for results of the pending shares until the next one times out, at most `check_s`;
        every `check_s` also find the (discipline, instance) pairs whose instance left the ROS
        graph. Returns (now in ns, those pairs, the time they were last checked)."""
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
                addressed = {p.discipline for _, p in step.items if p.target} | {
                    d for d, _ in self._targets_of(step.items[0][1].request)}
                for d in addressed:
                    live = self._live(d) or sorted(self._present_instances(d)[0])
                    if live:
                        targets[d] = retry.pick(live, step.eid, tries)
                self.node.get_logger().warning(
                    f"data-flow share {step.eid} (rows {a}-{b}): {sorted(f'{d}@{t}' for d, t, _ in step.blame)} "
                    f"{step.why}; re-sent to {targets} (retry {tries + 1}/{self.retries})")
                self._send_flow_share(names, request, a, b, targets, partials, tries + 1)
        return gave_up

    @staticmethod
    def _targets_of(request) -> set[tuple[str, str]]:
        """(discipline, instance) of every addressed discipline of a share, from its request's tag."""
        tag = binding.parse_tag(request.header.frame_id) or {}
        out = set()
        for d, entry in tag.items():
            _, t = binding.split_target(entry)
            if t:
                out.add((d, t))
        return out

    # -- worker pools (pool.py) -----------------------------------------------------
    def _pool(self, name: str) -> pools.Pool:
        pool = self.pools.get(name)
        if pool is None:
            pool = self.pools[name] = pools.Pool(name)
        return pool

    def _poll_info(self, every_s: float = 0.25) -> None:
        """Take the discipline declarations that arrived during the run (an instance that joins
        gets work from the next batch on); at most every `every_s`, off the data-flow hot path."""
        now = time.monotonic()
        if now - self._info_t < every_s:
            return
        self._info_t = now
        self._waiter.take_all([(self._info_sub, lambda msg, _i: self._on_info(msg))])

    def _present_instances(self, name: str) -> tuple[set[str], int]:
        """(accepted instances of `name` reading its request topic now, readers of that topic)."""
        accepted = self.instances.get(name, set())
        infos = self.node.get_subscriptions_info_by_topic(request_topic(name))
        present = set()
        for i in infos:
            full = f"{i.node_namespace.rstrip('/')}/{i.node_name}".lstrip("/")
            if full in accepted:
                present.add(full)
            elif i.node_name in accepted:
                present.add(i.node_name)
        return present, len(infos)

    def _live(self, name: str) -> list[str] | None:
        """The instances of `name` a batch is split among (None: send it as one request)."""
        if self.pool_mode != "share" or len(self.instances.get(name, ())) < 2:
            return None
        pool = self._pool(name)
        present, readers = self._present_instances(name)
        live = sorted(present - pool.suspect)
        # a reader our writer has not matched yet (one that just joined) gets work from a later batch
        if self._publisher(name).get_subscription_count() < readers and pool.stats:
            known = [i for i in live if pool.stat(i).shares > 0]
            live = known or live
        return live

    def wait_for_instances(self, name: str, count: int, wait_s: float) -> list[str]:
        """Block until `count` accepted instances of `name` read its request topic and our writer
        matched them all (a pool ready to share); returns them. DisciplineMissing once nothing
        changed for `wait_s` (fastwait.until)."""
        self._publisher(name)

        def ready() -> bool:
            self._info_t = 0.0
            self._poll_info()
            present, readers = self._present_instances(name)
            return len(present) >= count and self._publisher(name).get_subscription_count() >= readers

        if not until(ready, wait_s, functools.partial(self._executor.spin_once, timeout_sec=0.05),
                     functools.partial(self.progress, [name]), f"{count} instances of {name!r}"):
            raise DisciplineMissing(f"{len(self._present_instances(name)[0])} of {count} instances of {name!r} "
                                    f"(nothing changed for {wait_s:g} s)" + (f"; refused {self.refused}" if self.refused else ""))
        return sorted(self._present_instances(name)[0])

    def _send_shares(self, index: int, name: str, batch: Mapping[str, np.ndarray], iteration: int,
                     first: int, n: int, live: list[str], tries: int = 0) -> None:
        """Send rows first..first+n of `batch` as one share per instance in `live`."""
        fp = (self._expect(name) or ("?", ""))[0]
        self._batches[index] = (name, batch)
        for inst, a, b in self._pool(name).split(n, live, min_rows=pools.min_rows_of(self.pool_min_rows, name)):
            eid = self.ledger.new_id()
            req = self._request(eid, name, {k: np.asarray(v)[first + a:first + b] for k, v in batch.items()},
                                binding.target_tag(name, fp, inst), iteration=iteration, attempt=tries)
            p = self.ledger.open(eid, name, _Pending(index, name, req, b - a, 0, target=inst, start=first + a,
                                                     tries=tries))
            self._send(p)

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
                    self.node.get_logger().warning(f"no answer from {[p.discipline]} for evaluation "
                                                   f"{p.request.evaluation_id}; retry {p.tries}/{self.retries}")
                    self._send(p)
                    continue
                self.ledger.reassign(key)
                live = self._live(p.discipline) or []
                if not live:  # every instance failed: try them all again rather than give up early
                    live = sorted(self._present_instances(p.discipline)[0]) or [p.target]
                self.node.get_logger().warning(
                    f"{p.discipline} instance {p.target!r} {step.why} holding {p.n} design(s); "
                    f"re-sent to {live} (retry {p.tries + 1}/{self.retries})")
                name, batch = self._batches[p.index]
                self._send_shares(p.index, name, batch, iteration, p.start, p.n, live, tries=p.tries + 1)

    def pool_summary(self) -> dict[str, dict[str, dict]]:
        """{discipline: {instance: work, throughput, failures}} for every discipline with a pool."""
        return {d: {i: s.to_dict() for i, s in sorted(p.stats.items())}
                for d, p in sorted(self.pools.items()) if any(s.shares or s.failures for s in p.stats.values())}

    def _await(self) -> None:
        """Wait for every pending result; re-send what times out; fail what never answers."""
        for attempt in range(self.retries + 1):
            self._take_until(time.monotonic() + self.timeout_s)
            if not self._pending:
                break
            if attempt < self.retries:
                for p, late in retry.resend_round(self._pending, attempt + 1):
                    self.retried += len(late)
                    p.request.attempt = p.tries
                    self.node.get_logger().warning(
                        f"no answer from {late} for evaluation {p.request.evaluation_id} "
                        f"after {self.timeout_s:g} s; retry {attempt + 1}/{self.retries}"
                    )
                    self._send(p)
        unanswered = dict(self._pending)
        for key, p in unanswered.items():
            self._give_up(key, p)
        for d in retry.hung(unanswered, self._sources_of):
            if d not in self.unresponsive:
                # a discipline that let every attempt time out is hung (or gone): say so once, and
                # fail its later requests at once instead of waiting the whole timeout each time
                self.unresponsive.add(d)
                self.node.get_logger().error(
                    f"discipline {d!r} did not answer within {self.retries + 1} x {self.timeout_s:g} s: "
                    "its points fail, and so do its later requests, at once")

    def _give_up(self, key: tuple[int, str], p: _Pending) -> None:
        """Every attempt of `p` timed out: its points fail, named (a late answer is then dropped as a
        duplicate, never used)."""
        res = self._failed(p, self.policy.no_answer(p.discipline))
        self._first_error(p.discipline, res.error)
        self.ledger.close(key)
        if p.start >= 0:
            self._shares.add(key[0], p.index, p.start, res)
        else:
            self._results[p.index] = res

    def _sources_of(self, p: _Pending) -> set[str]:
        """The sources a data-flow entry's discipline reads from (none for hub and spoke)."""
        return set(((self.flow_plan(list(p.request.flow)) or {}).get(p.discipline) or {}).values())

    def _take_until(self, deadline: float, once: bool = False) -> None:
        """Take results until nothing is pending or the monotonic `deadline` (s) passed (no re-send);
        with ``once`` one wait at most. rcl wait sets are level-triggered: what arrived before this
        wait is ready at once."""
        subs = [s for s, _ in self._hot]
        while self._pending:
            left = deadline - time.monotonic()
            if left <= 0 and not once:
                return
            if self._waiter.wait(subs, max(0.0, left)):
                self._waiter.take_ready(self._hot)
            if once:
                return

    def spin(self, timeout_s: float) -> None:
        """Serve the node's callbacks (declarations, a recorder's status) for up to `timeout_s`."""
        self._executor.spin_once(timeout_sec=timeout_s)

    def close(self) -> None:
        """Release the executor (the node is the caller's)."""
        self._executor.remove_node(self.node)
        self._executor.shutdown()
