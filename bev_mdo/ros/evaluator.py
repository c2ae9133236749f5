"""The ROS transport of the engine's Evaluator interface: it moves the requests and answers.

What is sent, when, and what an answer means is the orchestration (mdo/orchestrator.py: waves,
data-flow MDAs, pools' shares, retries, the ledger); this subclass puts it on ROS topics. A wave is
one EvaluationRequest per (discipline, batch) on /bev_mdo/<discipline>/request, answered on
/bev_mdo/result. A feed-forward MDA (``evaluate_flow``, mdo/flow.py) is ONE request on
/bev_mdo/mda_request naming the disciplines, read by those without sources; every result
(/bev_mdo/<discipline>/mda_result) forwards the request's columns, so a consumer needs only its
sources' results, and the coordinator collects every discipline's result there. It is used only
when every node declared (DisciplineInfo) that it reads each coupling input from the same
producer as the coordinator's graph; otherwise the MDA runs in waves.

A result is accepted only if run id, evaluation id, discipline, binding (the request's frame_id:
binding.py) and batch shape match an outstanding request, so a result can never be matched to the
wrong evaluation; other-run, stale, duplicate and malformed results are dropped and counted. With
a shared key (``ros.sign_key_file``, see protocol/signing.py) every request is signed and every
result verified first; unsigned, forged, expired and replayed results are dropped and counted under
those names. Every accepted result is logged in ``accepted`` as (evaluation id, discipline,
instance, attempt sent so far), so a test can check that each evaluation id was accepted once,
from its own discipline.
"""
from __future__ import annotations

import time
import uuid
from typing import Mapping, Sequence

import numpy as np
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message

from bev_mdo import protocol
from bev_mdo.mdo import retry
from bev_mdo.mdo.discipline import EvalResult, all_finite, finite_rows
from bev_mdo.mdo.evaluator import DisciplineSpec
from bev_mdo.mdo.orchestrator import Orchestrator
from bev_mdo.protocol.signing import Signer
from bev_mdo import binding
from bev_mdo.ros.common import (DECLARATION_READER_QOS, INFO_TOPIC, MDA_REQUEST_TOPIC, REQUEST_QOS, RESULT_QOS,
                                RESULT_TOPIC, mda_result_topic, request_topic, stamp)
from bev_mdo.ros.fastwait import MultiWaiter
from bev_mdo.ros.startup import DisciplineMissing, StartupWaits  # noqa: F401 - DisciplineMissing re-exported
from bev_mdo.ros_settings import validate_min_rows
from bev_mdo_msgs.msg import DisciplineInfo, EvaluationRequest, EvaluationResult

_STATUS_REJECTED = EvaluationResult.STATUS_REJECTED  # read once: a metaclass property call each time
_Pending = retry.Sent  # an outstanding answer (mdo/retry.py), by the name the tests use


class RosEvaluator(StartupWaits, Orchestrator):
    """Evaluator over ROS topics; same interface as the in-process evaluator (start-up waits:
    startup.py; what is sent when, and retries: mdo/orchestrator.py)."""

    def __init__(self, node: Node, *, run_id: str | None = None, timeout_s: float = 5.0, retries: int = 3,
                 signer: Signer | None = None, config: Mapping | None = None):
        if config:  # the run's config, parsed once (config.RunConfig)
            from bev_mdo.config import RunConfig

            config = RunConfig.of(config)
        ros = config.ros if config else {}
        super().__init__(run_id=run_id or uuid.uuid4().hex[:16], timeout_s=timeout_s, retries=retries,
                         pool_mode=ros.get("pool", "share"),
                         # False: an MDA with a pool runs in waves (docs/scaling.md)
                         pool_data_flow=ros.get("pool_data_flow", True) is not False,
                         pool_min_rows=validate_min_rows(ros.get("pool_min_rows", 1)))
        self.node = node
        self.log = node.get_logger()
        if signer is None and config:  # sign if the run config names a key file
            signer = Signer.from_ros(ros)
        self.signer = signer
        # Binding (binding.py): the fingerprint every discipline of this run must have. Without a
        # config (a bare evaluator in a tool) the first declared fingerprint of a discipline is taken.
        self._config = config or None
        self.expected: dict[str, tuple[str, str]] = {}   # discipline -> (fingerprint, effective JSON)
        self._tags: dict[tuple, str] = {}                # names -> their request frame_id (_tag)
        self.instances: dict[str, set[str]] = {}         # discipline -> accepted instance names
        self.refused: dict[str, str] = {}                # "discipline instance" -> why it was refused
        self.other_runs: dict[str, set] = {}  # discipline -> run ids its nodes bound to other runs declared
        self._seq = 0
        self._publishers = {}
        self._flow_pub = None
        self._flow_subs: dict[str, object] = {}
        self._info_t = time.monotonic()
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        # Raw CDR in and out (the protocol's generated codec): rclpy's message objects cost more than the DDS hop.
        self._result_sub = node.create_subscription(EvaluationResult, RESULT_TOPIC, self._on_bytes, RESULT_QOS,
                                                    raw=True)
        # raw too: a signature covers the bytes as they were sent (protocol/signing.py)
        self._info_sub = node.create_subscription(DisciplineInfo, INFO_TOPIC, self._on_info, DECLARATION_READER_QOS,
                                                  raw=True)
        self._waiter = MultiWaiter(node.context)
        self._hot = [(self._result_sub, lambda data, _i: self._on_bytes(data))]
        self.local_requests = None  # composed.Beside: (publisher, request) -> True if delivered in process
        self.starting = None  # start-up progress of the run's own processes (launcher.Launcher.progress)

    @property
    def request_publishers(self) -> list:
        """Every request publisher this evaluator made (one per discipline, and the data-flow one)."""
        return list(self._publishers.values())

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
            self.log.warning(f"refused {msg.discipline!r} instance {msg.instance!r}: {why}")

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
            runs = self.other_runs.setdefault(msg.discipline, set()) if msg.discipline in self._publishers else set()
            if len(runs) < 4:  # named by start-up's error (a hint): of the run's disciplines, bounded
                runs.add(msg.run_id[:64])
            return None
        if self.signer is not None:
            why = self.signer.verify_info(data)
            if why is not None:
                self.dropped[f"info_{why}"] += 1
                return self._refuse(msg, f"{why} declaration ({'no key' if why == 'unsigned' else 'another key'}: "
                                         "ros.sign_key_file must name the same key for the run and its nodes)")
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
            res = self._rejected(p, msg.error)
        else:
            try:
                res = self._result_of(msg, p)
            except protocol.WireError:
                self.dropped["malformed"] += 1
                return
        self._accept(key, p, res, msg.instance)

    def _result_of(self, msg, p: retry.Sent) -> EvalResult:
        """The EvalResult a received answer to `p` holds; WireError if any field does not fit `p`."""
        outputs = protocol.from_named_array(msg.outputs)
        spec = self.specs.get(p.discipline)
        want = spec.outputs if spec else tuple(outputs)
        ok = np.asarray(msg.point_ok, dtype=bool)
        if any(k not in outputs for k in want) or int(msg.outputs.batch_size) != p.n or ok.shape != (p.n,):
            raise protocol.WireError("outputs or rows do not fit the request")
        outs = {k: np.array(outputs[k]) for k in want}
        ok = np.array(ok) if all_finite(outs.values()) else ok & finite_rows(list(outs.values()), p.n)
        why = protocol.point_errors_of(msg, p.n)
        res = EvalResult(outs, ok, msg.error, float(msg.compute_time_s), point_errors=why)
        if p.request.partials:
            part = protocol.partials_of(msg.partials, p.n)
            if part is not None:
                res.extra["partials"] = {k: np.array(v) for k, v in part.items()}
        return res

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
            res = self._rejected(p, error)
        elif np.shape(res.ok) != (p.n,):  # a node's answer to other rows than the ledger's (a bug)
            self.dropped["malformed"] += 1
            return
        self._accept(key, p, res, instance)

    def _tag(self, names, targets: Mapping[str, str] | None = None) -> str:
        """frame_id binding a request to this run's fingerprint of every named discipline and, for a
        pool's share, to one instance of each discipline in `targets` (binding.TARGET_SEP)."""
        key = tuple(names)
        tag = None if targets else self._tags.get(key)
        if tag is None:
            fps = {n: (self._expect(n) or ("?", ""))[0] for n in names}
            if targets:
                return binding.tag({n: f"{fp}{binding.TARGET_SEP}{targets[n].lstrip('/')}" if n in targets else fp
                                    for n, fp in fps.items()}, names)
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


    # -- worker pools (mdo/pool.py) --------------------------------------------------

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
        return self._present_on(name, request_topic(name))

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

    def _take_until(self, deadline: float, once: bool = False) -> None:
        """Take results until nothing is pending or the monotonic `deadline` (s) passed (no re-send);
        with ``once`` one wait at most; past it, what is ready is taken (a node composed here may answer
        late: Beside). rcl wait sets are level-triggered: what arrived before this wait is ready at once."""
        subs = [s for s, _ in self._hot]
        while self._pending:
            left = deadline - time.monotonic()
            if self._waiter.wait(subs, max(0.0, left)):
                self._waiter.take_ready(self._hot)
            if once or left <= 0:
                return

    def spin(self, timeout_s: float) -> None:
        """Serve the node's callbacks (declarations, a recorder's status) for up to `timeout_s`."""
        self._executor.spin_once(timeout_sec=timeout_s)

    def close(self) -> None:
        """Release the executor (the node is the caller's)."""
        self._executor.remove_node(self.node)
        self._executor.shutdown()
