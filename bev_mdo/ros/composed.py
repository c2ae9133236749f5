"""Several discipline nodes in one process: one executor, several nodes, still talking over topics.

Cheap disciplines gain nothing from a process each on a small host: every process decodes,
computes and encodes in its own interpreter and the processes contend for the cores. Like a
ROS 2 component container, this runs several DisciplineNode objects in one process; each keeps
its own name, topics and declaration, so the graph, the binding, the recordings and the
coordinator see exactly what they see with one process per discipline (the messages between
them still go through DDS, as rclpy has no intra-process path; but see Beside and link_local).

``ros2 run bev_mdo composed_node --ros-args -p config:=run.yaml -p disciplines:=vehicle_mass,energy``
(``python -m bev_mdo.ros.run composed_node ...``; ``instance`` and ``run_id`` parameters as for the
discipline node; each node is named ``<discipline>_node`` plus ``_<instance>`` when given).
The launcher's ``--compose all|none|GROUPS`` starts these (processes.py: composed_argv).
"""
from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rcl_interfaces.msg import ParameterDescriptor

from bev_mdo.config import RunConfig
from bev_mdo.mdo.discipline import DisciplineError
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.timed import TimedDiscipline
from bev_mdo.mdo.vectors import ShapeError
from bev_mdo import protocol
from bev_mdo.ros.discipline_node import DisciplineNode, serve, valid_run_id


def make_nodes(config, disciplines: list[str], instance: str = "", run_id: str = "",
               context=None) -> list[DisciplineNode]:
    """One DisciplineNode per discipline, sharing `config` (node names as the launcher gives them)."""
    config = RunConfig.of(config)
    nodes = []
    for name in disciplines:
        node_name = f"{name}_node" + (f"_{instance}" if instance else "")
        overrides = [Parameter("run_id", value=run_id)]
        if instance:
            overrides.append(Parameter("instance", value=node_name))
        nodes.append(DisciplineNode(name, config=config, node_name=node_name, parameter_overrides=overrides,
                                    context=context))
    return nodes


def link_local(nodes: list[DisciplineNode]) -> None:
    """Data flow inside the process: a node's data-flow result goes to the consumers composed with it
    by a direct call (after it is published, so the coordinator and any recorder see the same
    traffic), not through DDS, a decode and a signature check. Their subscriptions to it stay (the graph looks the same
    to the coordinator and to recorders) but are not read."""
    by_name = {node.discipline_name: node for node in nodes}
    for node in nodes:
        node.local_sources = {s for s in set(node.source_of.values()) if s in by_name}
        for src in sorted(node.local_sources):
            if node not in by_name[src].local_consumers:
                by_name[src].local_consumers.append(node)
            # An executor spinning the node (serve_many spins one for the parameter services) takes
            # what such a subscription queued: it must not evaluate the result a second time (before
            # this, every such spin made the consumer answer again and the coordinator count a
            # "duplicate": 130-520 per 5000 MDAs in bench_pool's composed layout).
            node._source_subs[src].callback = _already_served


def _already_served(_msg) -> None:
    """Callback of a data-flow subscription whose source is composed in the same process (link_local)."""


class Beside:
    """Discipline nodes composed into the coordinator's own process (``--compose coordinator``).

    The nodes are created in the coordinator's context (one DDS participant) and served from the
    coordinator evaluator's own wait loop (one thread, no other executor). Every node keeps its
    name, topics and declaration, so the graph and the handshake are those of any other layout.
    Messages between the coordinator and these nodes go as rclcpp's intra-process communication
    does: by direct call when no reader outside this process has matched the topic, else published
    (and then taken from DDS as usual), so a recorder or any other reader gets every message it
    gets with any other layout. A request goes to the nodes' handlers (``local_requests``); data
    flow between the nodes goes by direct call always (``link_local``). With nobody else listening
    an MDA then costs no DDS write at all.

    A direct call never encodes, decodes, signs or verifies. A request is handed over as the message
    object, its columns one NamedArray (``protocol.batch``). A result is not a message at all: a
    node hands the coordinator its ``run_discipline`` result (``DisciplineNode._direct``,
    ``RosEvaluator.on_local``), checked once, taken as the in-process evaluator takes it. And when
    every discipline of a data-flow MDA is a node here and none of their result topics has an
    outside reader, the whole MDA is one call into the in-process evaluator's flow engine
    (``_flow``): no result message is built, none is checked twice. Kept on these paths: run id,
    binding tag (fingerprints, a pool's target), evaluation id, discipline and binding against the
    coordinator's ledger (stale, duplicate, mismatched), ``run_discipline``'s checks (inputs, output
    shapes, non-finite points named), the data-flow rule. Dropped, because they exist only against
    forgery or a corrupted wire and nothing outside this process can make the call: the HMAC
    signature with its freshness and replay window, the codec's checks of undecodable bytes and
    variable names, and the receiver's second check of a result's shapes, flags and point errors.
    A message that is published (a reader outside matched its topic) is encoded, signed, verified
    and checked field by field exactly as in every other layout.

    Not served: the nodes' parameter services (no executor spins them) and requests from another
    process's coordinator while this one is not evaluating (the nodes are served only inside the
    coordinator's waits). A call is bounded as in process (mdo/timed.py): a discipline that overran
    ros.timeout_s x (ros.retries + 1) fails its points, named, and is hung for the coordinator (_served)."""

    def __init__(self, config, names: list[str], context, run_id: str = "", instance: str = ""):
        self.nodes = make_nodes(config, list(names), instance, run_id, context=context)
        ros = RunConfig.of(config).ros  # a call in this thread cannot be waited for, only bounded
        for node in self.nodes:
            node.discipline = TimedDiscipline(node.discipline, ros["timeout_s"] * (ros["retries"] + 1), True)
        link_local(self.nodes)
        self._pairs: list = []
        self._evaluator = None
        # a whole data-flow MDA by one call (_flow): the flow engine over the nodes' disciplines
        self._engine = InProcessEvaluator(node.discipline for node in self.nodes)
        self._flows: dict[tuple, list] = {}    # the MDA's disciplines -> their nodes ([]: not all here)
        self._bound: set[tuple[str, str]] = set()  # (run id, tag) every node checked as its own

    def attach(self, evaluator) -> None:
        """Serve the nodes from `evaluator`'s waits and hand their results to it (one at a time)."""
        self.detach()
        self._evaluator = evaluator
        for node in self.nodes:
            # the in-process readers of its result topics: the coordinator's, and the subscriptions of
            # the consumers composed with it (kept in the graph, not read: link_local)
            node.local_readers = {id(node._mda_pub): 1 + len(node.local_consumers), id(node._result_pub): 1}
            node.local_coordinator = evaluator.on_local
            for sub, handle in node.hot_subscriptions():  # then node stats, a discipline that hung (_served)
                self._pairs.append((sub, lambda data, info, h=handle: (h(data, info), self._served())))
        evaluator._hot.extend(self._pairs)
        # requests: as rclcpp's intra-process communication, by direct call to the nodes of this
        # process when no reader outside it matched the topic (else published, and taken from DDS)
        self._local, self._by_pub = {}, {}
        for node in self.nodes:
            self._local.setdefault(node._sub.topic_name, []).append((node, node._on_request))
            if node._mda_sub is not None:
                self._local.setdefault(node._mda_sub.topic_name, []).append((node, node._on_mda_request))
        evaluator.local_requests = self._deliver

    def _deliver(self, pub, request) -> bool:
        local = self._by_pub.get(id(pub))
        if local is None:
            local = self._by_pub[id(pub)] = self._local.get(pub.topic_name, [])
        if not local or pub.get_subscription_count() > len(local):
            return False
        if request.flow and self._flow(request):
            return True
        for _node, handle in local:
            handle(request, local=True)
        self._served()
        return True

    def _served(self) -> None:
        for node in self.nodes:  # the consumers' too (they answered by link_local's direct calls)
            node.publish_stats()  # rate-limited (node stats, `bev-mdo status`)
            if node.discipline.hung:  # overran ros.timeout_s x (ros.retries + 1): as a node that never answers
                self._evaluator.mark_hung(node.discipline_name)

    def _flow(self, req) -> bool:
        """A whole data-flow MDA in one call, when every discipline of it is a node here and no
        reader outside this process matched any of their result topics: the MDA is evaluated by
        the in-process evaluator's flow engine (InProcessEvaluator.evaluate_flow, mdo/flow.py: the
        rule each node applies with its sources' results) over the nodes' own discipline objects,
        and each node's result goes to the coordinator as an EvalResult (``on_local``), as the
        nodes would hand it one by one, with the nodes' counters moved as theirs. Every node's
        binding check (run, fingerprint in the request's tag) is made once per run and tag.
        False (the nodes then take the request one by one, as messages) when any of it does not
        hold, or when a discipline raises what a node would answer with a rejection."""
        names = tuple(req.flow)
        nodes = self._flows.get(names)
        if nodes is None:
            by_name = {node.discipline_name: node for node in self.nodes}
            nodes = self._flows[names] = [by_name[d] for d in names] if set(names) <= set(by_name) else []
        if not nodes:
            return False
        for node in nodes:
            w = node._mda_pub
            if w.get_subscription_count() > node.local_readers.get(id(w), 0):
                return False
        bound = (req.run_id, req.header.frame_id)
        if bound not in self._bound:
            if not (valid_run_id(req.run_id) and all(node.unbound(req) is None for node in nodes)):
                return False
            if len(self._bound) > 256:  # a run has a handful of tags; sub-runs and probes add a few
                self._bound.clear()
            self._bound.add(bound)
        n = int(req.inputs.batch_size)
        try:
            got = self._engine.evaluate_flow(names, protocol.from_named_array(req.inputs), n, bool(req.partials))
        except (ShapeError, DisciplineError, KeyError, protocol.WireError):
            return False
        if got is None:
            return False
        hand = self._evaluator.on_local
        for node in nodes:
            res = got[node.discipline_name]
            node.counts["received"] += 1
            node._answered(res)
            hand(req, node.discipline_name, node.instance, res)
        self._served()
        return True

    def detach(self) -> None:
        if self._evaluator is not None:
            hot = self._evaluator._hot
            hot[:] = [p for p in hot if all(p is not q for q in self._pairs)]
            self._evaluator.local_requests = None
        for node in self.nodes:
            node.local_coordinator = None
        self._pairs, self._evaluator = [], None

    def close(self) -> None:
        self.detach()
        for node in self.nodes:
            node.destroy_node()
        self.nodes = []


def serve_many(nodes: list[DisciplineNode], idle_s: float = 0.1, service_every: int = 64) -> None:
    """Serve the nodes composed in this process: linked for data flow (link_local), then the one serve
    loop (discipline_node.serve) over all of them."""
    link_local(nodes)
    serve(nodes, idle_s, service_every)


def main(args: list[str] | None = None) -> int:
    """Run the named disciplines in this process until Ctrl-C / SIGTERM."""
    from bev_mdo.ros.paths import default_config

    rclpy.init(args=args)
    nodes: list[DisciplineNode] = []
    try:
        probe = Node("composed_params")
        for key, desc in (("config", "run config YAML"),
                          ("disciplines", "comma-separated discipline names to serve in this process"),
                          ("instance", "instance suffix of every node name"), ("run_id", "serve only this run")):
            # dynamic typing: an instance or run id of hex digits ("8469814e") parses as a number
            probe.declare_parameter(key, "", ParameterDescriptor(description=desc, dynamic_typing=True))
        p = {k: probe.get_parameter(k).value for k in ("config", "disciplines", "instance", "run_id")}
        p = {k: "" if v is None else (",".join(map(str, v)) if isinstance(v, (list, tuple)) else str(v))
             for k, v in p.items()}

        probe.destroy_node()
        names = [n.strip() for n in str(p["disciplines"]).strip("[]").split(",") if n.strip()]
        if not names:
            raise ValueError("composed_node needs -p disciplines:=name[,name...]")
        config = RunConfig.load(p["config"] or default_config())
        nodes = make_nodes(config, names, p["instance"], p["run_id"])
        serve_many(nodes)
    except (KeyboardInterrupt, ExternalShutdownException):
        if not nodes:  # stopped while loading: ros.run says so (one line, status 130 or 143)
            raise
    except Exception as exc:  # an rcl call racing the shutdown of a signalled context is a normal stop
        if rclpy.ok() and isinstance(exc, ValueError):
            print(f"composed_node: error: {exc}", file=sys.stderr)
            return 2
        if rclpy.ok() or not nodes:
            raise
    finally:
        from bev_mdo.stacks import deadline

        with deadline():  # as discipline_node.main: a teardown hung in Fast DDS must not outlive the run
            for node in nodes:
                node.destroy_node()
            if rclpy.ok():
                rclpy.shutdown()
    return 0
