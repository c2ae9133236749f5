"""One generic node that serves ANY discipline over ROS 2.

It subscribes to /bev_mdo/<discipline>/request, evaluates the batch with
`run_discipline` (bad points are isolated and named, never crash the node) and
publishes an EvaluationResult on /bev_mdo/result echoing run id and evaluation id.

Data flow (one request per feed-forward MDA, mdo/flow.py): the node also reads
/bev_mdo/mda_request and the /bev_mdo/<source>/mda_result topics of the disciplines that
produce its coupling inputs (found from the run config), evaluates once its sources have
answered, and publishes on its own /bev_mdo/<discipline>/mda_result.
Malformed requests are rejected, counted and logged (rate-limited). The node knows no physics:
the discipline object comes from the run config (built-in or `module:Class`).

Parameters: config (path to the run YAML), discipline (name in the config),
instance (defaults to the node name), and vehicle.<key> overrides of the config's
vehicle section.
"""
from __future__ import annotations

import functools
import sys
import time
from collections import Counter
from typing import Any

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from bev_mdo import __version__, binding, protocol
from bev_mdo.stacks import deadline
from bev_mdo.mdo import flow
from bev_mdo.mdo.discipline import DisciplineError, all_finite, prepare, readable, run_discipline, unknown_inputs
from bev_mdo.mdo.vectors import ShapeError, rejection
from bev_mdo.processes import check_parameters
from bev_mdo.protocol import node_stats
from bev_mdo.protocol.batches import decode_once
from bev_mdo.protocol.signing import Signer
from bev_mdo.ros.common import (INFO_QOS, INFO_TOPIC, MDA_REQUEST_TOPIC, MDA_RESULT_QOS, NODE_STATS_QOS,
                                NODE_STATS_TOPIC, REQUEST_QOS, RESULT_QOS, RESULT_TOPIC, declare, mda_result_topic,
                                request_topic, stamp)
from bev_mdo.ros.paths import default_config
from bev_mdo_msgs.msg import DisciplineInfo, EvaluationRequest, EvaluationResult
from std_msgs.msg import String

# the result status constants, read once (the generated class makes each a metaclass property call)
_STATUS_OK = EvaluationResult.STATUS_OK
_STATUS_ERROR = EvaluationResult.STATUS_ERROR
_STATUS_REJECTED = EvaluationResult.STATUS_REJECTED

FLOW_CACHE = 64  # data-flow requests and source results kept while they wait for each other

def _build(config, name: str) -> tuple[Any, dict[str, str]]:
    """(the discipline, prepared: its one-time work done; output -> producing discipline in the RunConfig)."""
    every = config.disciplines
    found = [d for d in every if d.name == name]
    if not found:
        raise ValueError(f"no discipline {name!r} in the config; it has {[d.name for d in every]}")
    prepare(found[0])  # e.g. compiling a model: before serving, not in a timed call
    return found[0], {v: d.name for d in every for v in d.outputs}


def valid_run_id(run_id: str) -> bool:
    """A run id a node serves: non-empty, printable, at most 128 characters."""
    return bool(run_id) and len(run_id) <= 128 and run_id.isprintable()


class DisciplineNode(Node):
    """Serves one discipline: request in, result out, per evaluation id."""

    def __init__(self, discipline: str | None = None, *, config: dict | None = None, **kwargs):
        name_hint = discipline or "discipline"
        super().__init__(kwargs.pop("node_name", f"{name_hint}_node"), **kwargs)
        p = {k: declare(self, k, default, desc) for k, default, desc in (
            ("config", "", "path to the run config YAML"), ("discipline", discipline or "", "discipline name"),
            ("instance", "", "instance name (default: node name)"),
            ("run_id", "", "serve only this run (and its <run>-... sub-runs); empty: any run whose requests "
                           "carry this node's configuration fingerprint"))}
        name = p["discipline"]
        if not name:
            raise ValueError("discipline_node needs -p discipline:=<name>")
        from bev_mdo.config import RunConfig

        alone = config is None  # started on its own (not composed): every -p of its command line is for it
        if alone and not p["config"]:  # the docs start every node with -p config:=FILE
            self.get_logger().warning(f"no -p config:=FILE given: serving the default run config {default_config()}")
        run_config = RunConfig.of(p["config"] or default_config() if alone else config)
        config = self._apply_overrides(run_config)
        if alone:  # an override it does not declare (a misspelt vehicle.<key>) is refused, not ignored
            own = [k for k in self._parameters if not (discipline and k == "discipline")]  # energy_node: none
            check_parameters(self._parameter_overrides, own, self.get_name())
            if p["instance"] and p["instance"].lstrip("/") != self.get_name():  # the graph knows nodes by name
                raise ValueError(f"-p instance:={p['instance']} does not rename the node (the coordinator looks for "
                                 f"its name): start it with -r __node:={p['instance']} or bev-mdo node {name} --instance")
        self.discipline, producer = _build(config, name)
        self.discipline_name = name
        self.bound_run = p["run_id"]
        self.fingerprint, self.effective_config = binding.fingerprint(config, name)
        self.source_of = flow.sources_of(self.discipline.inputs, producer, name)  # coupling input -> source
        self._allowed = readable(self.discipline)
        self.instance = p["instance"] or self.get_fully_qualified_name()
        self.counts: Counter[str] = Counter()
        self.compute_s = 0.0  # time spent in compute(), summed (node stats)
        self.signer = Signer.from_ros(run_config.ros)
        self._stats_pub = self.create_publisher(String, NODE_STATS_TOPIC, NODE_STATS_QOS)
        self._stats_sent: dict[str, int] | None = None
        self._stats_t = 0.0
        self._result_pub = self.create_publisher(EvaluationResult, RESULT_TOPIC, RESULT_QOS)
        self._info_pub = self.create_publisher(DisciplineInfo, INFO_TOPIC, INFO_QOS)
        # Raw CDR in and out (the protocol's generated codec): rclpy's message objects cost more than the DDS hop.
        self._sub = self.create_subscription(EvaluationRequest, request_topic(name),
                                             self._raw(self._on_request), REQUEST_QOS, raw=True)
        self._mda_pub = self.create_publisher(EvaluationResult, mda_result_topic(name), MDA_RESULT_QOS)
        # Data flow: a discipline with sources gets the request's columns with its sources' results,
        # so only the disciplines without sources read the request (fewer processes woken at once).
        self._mda_sub = None if self.source_of else self.create_subscription(
            EvaluationRequest, MDA_REQUEST_TOPIC, self._raw(self._on_mda_request), REQUEST_QOS, raw=True)
        self._outputs_of = {s: {v for v, p in producer.items() if p == s} for s in set(self.source_of.values())}
        self._source_subs = {
            src: self.create_subscription(EvaluationResult, mda_result_topic(src),
                                          self._raw(functools.partial(self._on_source_result, src), result=True),
                                          MDA_RESULT_QOS, raw=True)
            for src in sorted(set(self.source_of.values()))}
        self._join = flow.FlowJoin(self.source_of, self._outputs_of, FLOW_CACHE)  # (run, eval id) -> sources' results
        # Composed (composed.py: link_local): nodes of this process that consume our data-flow results
        # get them by a direct call after the publish, and sources in this process are not read from DDS.
        self.local_consumers: list[DisciplineNode] = []
        self.local_sources: set[str] = set()
        # Composed beside the coordinator (composed.Beside): an answer goes to it by direct call, as the
        # discipline's EvalResult (RosEvaluator.on_local), when no reader but the in-process ones
        # (local_readers: writer id -> their number) has matched the topic (_direct).
        self.local_coordinator = None
        self.local_readers: dict[int, int] = {}
        self._publish_info()
        self.get_logger().info(
            f"serving {name!r}: inputs {list(self.discipline.inputs)} -> outputs {list(self.discipline.outputs)}"
            + f"; fingerprint {self.fingerprint}"
            + (f"; bound to run {self.bound_run}" if self.bound_run else "; standalone")
            + ("; requests must be signed" if self.signer else "")
        )
        self.publish_stats(force=True)

    def publish_stats(self, force: bool = False, every_s: float = 0.1) -> None:
        """Publish the counters on /bev_mdo/node_stats if they changed (at most every `every_s`)."""
        now = time.monotonic()
        if not force and now - self._stats_t < every_s:
            return
        snap = dict(self.counts)
        if not force and snap == self._stats_sent:
            return
        msg = String()
        msg.data = node_stats.payload(self.discipline_name, self.instance, snap, self.bound_run, self.fingerprint,
                                      self.compute_s)
        self._stats_pub.publish(msg)
        self._stats_sent, self._stats_t = snap, now

    def _apply_overrides(self, run_config):
        """Declare vehicle.<key> parameters (a whole number is taken for a DOUBLE); values set on the
        command line override the YAML (RunConfig.with_vehicle)."""
        return run_config.with_vehicle({k: declare(self, f"vehicle.{k}", float(v))
                                        for k, v in (run_config.data.get("vehicle") or {}).items()
                                        if isinstance(v, (int, float)) and not isinstance(v, bool)})

    def _publish_info(self) -> None:
        d = self.discipline
        msg = DisciplineInfo()
        stamp(msg.header)
        msg.discipline = self.discipline_name
        msg.instance = self.instance
        msg.class_name = f"{type(d).__module__}:{type(d).__name__}"
        msg.inputs = list(d.inputs)
        msg.outputs = list(d.outputs)
        msg.parameters = list(getattr(d, "parameters", {}) or {})
        msg.version = __version__
        msg.coupling_inputs = list(self.source_of)
        msg.coupling_sources = list(self.source_of.values())
        msg.run_id = self.bound_run
        msg.fingerprint = self.fingerprint
        msg.effective_config = self.effective_config
        self._info_pub.publish(msg if self.signer is None else self.signer.sign_info(msg))  # signed: its bytes

    def _raw(self, handle, result: bool = False):
        """A raw-subscription callback: decode the CDR bytes, count what does not decode."""
        decode = protocol.decode_result if result else protocol.decode_request

        def on_bytes(data: bytes) -> None:
            try:
                msg = decode_once(decode, data)  # decoded once for the nodes of a process
            except protocol.WireError as exc:
                self.counts["rejected"] += 1
                self.counts["rejected.undecodable"] += 1
                self.get_logger().warning(f"dropped an undecodable message: {exc}", throttle_duration_sec=2.0)
                return
            handle(msg)

        return on_bytes

    def hot_subscriptions(self) -> list:
        """(subscription, handler(data, info)) of everything served on the hot path."""
        subs = [self._sub, *([self._mda_sub] if self._mda_sub else []),
                *(sub for src, sub in self._source_subs.items() if src not in self.local_sources)]
        return [(sub, lambda data, _info, f=sub.callback: f(data)) for sub in subs]

    def _reject(self, req: EvaluationRequest, why: str, category: str = "malformed", pub=None) -> None:
        self.counts["rejected"] += 1
        self.counts[f"rejected.{category}"] += 1
        self.get_logger().warning(
            f"rejected request (run {req.run_id[:40]!r}, eval {req.evaluation_id}): {why[:200]} "
            f"[{self.counts['rejected']} rejected so far; this log is rate-limited]", throttle_duration_sec=2.0
        )
        self._reply(req, None, rejection(self.discipline_name, why, category)[:1000], pub)

    def _direct(self, writer) -> bool:
        """True when composed beside the coordinator (composed.Beside) and no reader outside this
        process (``local_readers``: writer id -> their number) matched `writer`'s topic: the answer
        then goes to the coordinator by a direct call (``local_coordinator``), as the discipline's
        EvalResult, never as a message (nothing encoded, signed or even built for it)."""
        return (self.local_coordinator is not None
                and writer.get_subscription_count() <= self.local_readers.get(id(writer), 0))

    def _reply(self, req, result, error: str = "", pub=None, forward=None, flow_names=None, asked=False) -> None:
        """Answer `req` with the discipline's `result` (None: a rejection saying `error`) on `pub` (data
        flow) or the result topic, signed with a key, unless the coordinator takes it by direct call;
        composed consumers (link_local) get it by direct call, without a DDS hop and a decode."""
        writer = pub or self._result_pub
        consumers = self.local_consumers if pub is self._mda_pub else ()
        direct = self._direct(writer)
        if direct:
            self.local_coordinator(req, self.discipline_name, self.instance, result, error)
            if not consumers:  # beside the coordinator, nobody else reads it: no message at all
                return
        out = protocol.result()
        stamp(out.header)
        out.header.frame_id = req.header.frame_id
        out.run_id = req.run_id
        out.evaluation_id = req.evaluation_id
        out.sequence = self.counts["answered"] + self.counts["rejected"]
        out.discipline = self.discipline_name
        out.instance = self.instance
        if result is None:
            out.status = _STATUS_REJECTED
            out.error = error
            if pub is not None:  # data flow: consumers learn that there is nothing to wait for
                out.flow = list(req.flow)
        else:
            out.status = _STATUS_OK if result.ok.all() else _STATUS_ERROR
            out.error = result.error[:4000]
            protocol.put_point_errors(out, result.point_errors)
            out.point_ok = np.asarray(result.ok, dtype=bool)
            out.outputs = protocol.batch({**result.outputs, **forward} if forward else result.outputs)
            out.flow = list(flow_names or ())
            out.compute_time_s = result.compute_time_s
            if asked:
                # a block of the batch size even without partials: downstream nodes learn it was asked
                out.partials = protocol.partials_batch(result.extra.get("partials", {}), int(np.size(result.ok)))
        if not direct:
            writer.publish(protocol.encode_result(out) if self.signer is None else self.signer.sign_result(out))
        for node in consumers:
            node._on_source_result(self.discipline_name, out, local=True)

    def _for_me(self, msg, source: str | None = None) -> bool:
        """True if `msg` belongs to a run this node serves and binds this node's own fingerprint
        (and, for a source's result, that source's too). Anything else is another run's or another
        configuration's traffic on the shared topics: ignored without an answer, counted."""
        why = self.unbound(msg, source)
        if why is None:
            return True
        self.counts[f"ignored.{why}"] += 1
        return False

    def unbound(self, msg, source: str | None = None) -> str | None:
        """Why `msg` is not for this node (``other_run``, ``fingerprint``, ``other_instance``), or None."""
        if not binding.run_matches(self.bound_run, msg.run_id):
            return "other_run"
        want = binding.parse_tag(msg.header.frame_id) or {}
        fp, target = binding.split_target(want.get(self.discipline_name, ""))
        if fp != self.fingerprint or (source is not None and source not in want):
            return "fingerprint"
        if target and target != self.instance.lstrip("/"):  # a pool's share for another instance
            return "other_instance"
        return None

    def _on_request(self, req: protocol.EvaluationRequest, local: bool = False) -> None:
        """A request; ``local``: handed over by direct call in this process (composed.Beside), so its
        signature is not checked (nothing outside the process can make that call); all else is."""
        if not self._for_me(req):
            return None
        self.counts["received"] += 1
        if not local and not self._authentic(req, "request"):  # no answer: an unauthenticated sender learns nothing
            return None
        if req.discipline != self.discipline_name:
            return self._reject(req, f"addressed to {req.discipline[:40]!r}", "wrong_discipline")
        if not valid_run_id(req.run_id):
            return self._reject(req, "bad run id", "bad_run_id")
        try:
            inputs = protocol.from_named_array(req.inputs)
        except protocol.WireError as exc:
            return self._reject(req, str(exc), "malformed")
        missing = [k for k in self.discipline.inputs if k not in inputs]
        if missing:
            return self._reject(req, f"missing inputs {missing}", "missing_inputs")
        unknown = unknown_inputs(self._allowed, inputs)  # the entry check of every transport
        if unknown:
            return self._reject(req, f"unknown inputs {unknown[:5]}", "unknown_inputs")
        if not all_finite(inputs.values()):
            # evaluated anyway: those points fail (point_ok false, named), as in-process
            self.counts["non_finite"] += 1
        try:
            result = run_discipline(self.discipline, inputs, bool(req.partials))
        except (ShapeError, DisciplineError) as exc:  # the discipline's own mistake: name it, once
            return self._reject(req, str(exc), "bad_discipline_output")
        self._answer(req, result, asked=bool(req.partials))

    def _answer(self, req, result, pub=None, forward=None, flow_names=(), asked=False) -> None:
        self._answered(result)
        self._reply(req, result, "", pub, forward, flow_names, asked)

    def _answered(self, result) -> None:
        """Log the discipline's error (rate-limited) and count an answer (node stats)."""
        if result.error:
            self.get_logger().warning(result.error[:500], throttle_duration_sec=2.0)
        self.counts["answered"] += 1
        self.counts["points"] += int(np.size(result.ok))
        self.compute_s += float(result.compute_time_s or 0.0)

    # -- data flow -----------------------------------------------------------------
    def _authentic(self, msg, kind: str) -> bool:
        """True unless the run signs and `msg` (a `kind`: request, data-flow request or result) is not
        signed right: then it is counted and logged (rate-limited)."""
        if self.signer is None:
            return True
        why = (self.signer.verify_result if kind.endswith("result") else self.signer.verify_request)(msg)
        if why is None:
            return True
        self.counts["rejected"] += 1
        self.counts[f"rejected.{why}"] += 1
        self.get_logger().warning(
            f"dropped {why} {kind} (run {msg.run_id[:40]!r}, eval {msg.evaluation_id}) "
            f"[{self.counts['rejected']} rejected so far; this log is rate-limited]", throttle_duration_sec=2.0)
        return False

    def _on_mda_request(self, req: protocol.EvaluationRequest, local: bool = False) -> None:
        """A data-flow request, read by the disciplines without sources: evaluate now (``local``:
        by direct call in this process, as for _on_request)."""
        if self.discipline_name not in req.flow:
            return None  # an MDA without this discipline
        if not self._for_me(req):
            return None
        self.counts["received"] += 1
        if not local and not self._authentic(req, "data-flow request"):
            return None
        if not valid_run_id(req.run_id):
            return self._reject(req, "bad run id", "bad_run_id", self._mda_pub)
        try:
            inputs = protocol.from_named_array(req.inputs)
        except protocol.WireError as exc:
            return self._reject(req, str(exc), "malformed", self._mda_pub)
        self._flow_answer(req, inputs, {}, {}, int(req.inputs.batch_size), list(req.flow), bool(req.partials))

    def _on_source_result(self, source: str, msg: protocol.EvaluationResult, local: bool = False) -> None:
        """A source's data-flow result (it carries the request's columns too): keep it for
        (run, evaluation id) and evaluate once every source of this MDA has answered (``local``: by
        direct call from a source composed in this process, as for _on_request)."""
        if source not in msg.flow or self.discipline_name not in msg.flow:
            return  # not a data-flow MDA with this discipline
        if not self._for_me(msg, source):
            return
        if not local and not self._authentic(msg, "data-flow result"):
            return
        if msg.discipline != source:
            self.counts["source_malformed"] += 1
            return
        try:
            columns = protocol.from_named_array(msg.outputs)
        except protocol.WireError:
            self.counts["source_malformed"] += 1
            return
        try:  # the one join rule (mdo/flow.py): None until every source of this MDA has answered
            joined = self._join.add((msg.run_id, int(msg.evaluation_id)), source, columns, msg.point_ok,
                                    msg.flow, msg.status == _STATUS_REJECTED, msg,
                                    int(msg.outputs.batch_size))
        except flow.SourcesDisagree as exc:
            self.counts["received"] += 1
            return self._reject(msg, str(exc), "malformed", self._mda_pub)
        except flow.FlowError:
            self.counts["source_malformed"] += 1
            return
        if joined is None:
            return
        self.counts["received"] += 1
        if joined.rejected:  # no row to evaluate, and this node cannot know how many the request had:
            # rejected too, named, so the coordinator fails this discipline's rows at once (as in
            # process, where every row downstream of a rejected discipline fails), not at its timeout
            return self._reject(msg, f"source {', '.join(joined.rejected)} rejected the request",
                                "source_rejected", self._mda_pub)
        # partials were asked for the MDA when a source's result carries a partials block of its size
        n = joined.n
        asked = n > 0 and any(int(m.partials.batch_size) == n for m in joined.extras.values())
        self._flow_answer(msg, joined.request, joined.up, joined.sources, n, list(msg.flow), asked)

    def _flow_answer(self, req, request: dict, up: dict, sources: dict, n: int, flow_names: list[str],
                     asked: bool = False) -> None:
        """Evaluate for a data-flow MDA and publish; the result forwards the request's columns."""
        missing = [k for k in self.discipline.inputs if k not in sources and k not in request]
        if missing and n:
            return self._reject(req, f"missing inputs {missing}", "missing_inputs", self._mda_pub)
        try:
            result, _ = flow.run_flow_discipline(self.discipline, request, up, sources, n, asked)
        except (ShapeError, DisciplineError) as exc:
            return self._reject(req, str(exc), "bad_discipline_output", self._mda_pub)
        forward = {k: v for k, v in request.items() if k not in result.outputs}
        self._answer(req, result, self._mda_pub, forward=forward, flow_names=flow_names, asked=asked)


def serve(nodes: "DisciplineNode | list[DisciplineNode]", idle_s: float = 0.1, service_every: int = 64) -> None:
    """The one serve loop, until the context shuts down, of a standalone node or of the nodes composed in
    one process (composed.serve_many): hot subscriptions are taken from one wait set (fastwait), other
    entities (parameter services) spun by one executor when idle and every `service_every` requests."""
    from rclpy.executors import SingleThreadedExecutor

    from bev_mdo.ros.fastwait import MultiWaiter

    nodes = [nodes] if isinstance(nodes, DisciplineNode) else list(nodes)
    context = nodes[0].context
    executor = SingleThreadedExecutor(context=context)
    for node in nodes:
        executor.add_node(node)
    waiter = MultiWaiter(context)
    pairs = [pair for node in nodes for pair in node.hot_subscriptions()]
    subs = [s for s, _ in pairs]
    served = 0
    try:
        waiter.take_all(pairs)
        while context.ok():
            # rcl wait sets are level-triggered: wait() returns at once while anything is queued
            if waiter.wait(subs, idle_s):
                served += waiter.take_ready(pairs)
                if served < service_every:
                    continue
                served = 0
            for node in nodes:
                node.publish_stats()
            executor.spin_once(timeout_sec=0.0)
    finally:
        executor.shutdown()


def main(args: list[str] | None = None, discipline: str | None = None, config=None) -> int:
    """Run a discipline node until Ctrl-C / SIGTERM (``config``: the run's RunConfig, else the
    ``config`` parameter's file is loaded)."""
    rclpy.init(args=args)
    node, named = None, next((a[12:] for a in (args or sys.argv) if a.startswith("discipline:=")), "")  # its name
    try:  # discipline_node -p discipline:=top_speed: top_speed_node, as composed and `optimize` name it
        node = DisciplineNode(discipline, config=config, **({} if discipline or not named.isidentifier() else
                                                            {"node_name": f"{named}_node"}))
        serve(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        if node is None:  # stopped while loading: its caller says so (ros.run: one line, status 130 or 143)
            raise
    except Exception as exc:  # an rcl call racing the shutdown of a signalled context is a normal stop
        if rclpy.ok() and isinstance(exc, ValueError):
            print(f"{discipline or 'discipline'}_node: error: {exc}", file=sys.stderr)  # as its "starting" line
            return 2
        if rclpy.ok() or node is None:  # not a stop, or a signal while loading (the context shut down)
            raise
    finally:  # bounded: an orphan's SIGTERM cannot reach Python while Fast DDS blocks (stacks.deadline)
        with deadline():
            if node is not None:
                node.destroy_node()
            if rclpy.ok():
                rclpy.shutdown()
    return 0
