"""The coordinator: hosts the engine's driver with the ROS evaluator plugged in.

The same `run_optimization` runs in-process and here; only the evaluator differs.
Each iteration is published as an IterationRecord on /bev_mdo/iteration (and so
recorded by the recorder node).
"""
from __future__ import annotations

import json
import re
import sys
import time
import uuid
from typing import Any, Callable, Mapping

import rclpy
from rclpy.node import Node

from bev_mdo import jsontext, protocol
from bev_mdo.processes import beside_coordinator, check_parameters
from bev_mdo.ros.common import (ITERATION_QOS, ITERATION_TOPIC, RESULT_TOPIC, declare, endpoints, mda_result_topic,
                                stamp, wait_acked)
from bev_mdo.ros.evaluator import RosEvaluator
from bev_mdo.ros.fastwait import until
from bev_mdo.ros.recorder_node import OwnRecorder
from bev_mdo.stacks import STARTUP_GAVE_UP_STATUS, StartupGaveUp, teardown
from bev_mdo_msgs.msg import IterationRecord


def node_name_for(run_id: str, base: str = "coordinator") -> str:
    """A coordinator's node name of its own (``coordinator_<run id>``): a run's recorder declares the
    publishers it matched by node name, so two runs' coordinators must not share one."""
    return f"{base}_" + re.sub(r"\W", "_", run_id)[:24]


def discipline_names(config: Mapping[str, Any]) -> list[str]:
    """Names of the disciplines a run needs (a RunConfig's, or read from a resolved config)."""
    from bev_mdo.config import RunConfig, discipline_names as names

    return list(config.names) if isinstance(config, RunConfig) else names(config)


class CoordinatorNode(Node):
    """Publishes iteration records and owns the ROS evaluator."""

    def __init__(self, config: Mapping[str, Any], run_id: str | None = None, signer=None, **kwargs):
        from bev_mdo.config import RunConfig

        super().__init__(kwargs.pop("node_name", "coordinator_node"), **kwargs)
        self.config = config = RunConfig.of(config)
        ros = config.ros
        self.run_id = run_id or uuid.uuid4().hex[:16]
        self._seq = 0
        self._iteration_pub = self.create_publisher(IterationRecord, ITERATION_TOPIC, ITERATION_QOS)
        self.evaluator = RosEvaluator(self, run_id=self.run_id, timeout_s=ros["timeout_s"], retries=ros["retries"],
                                      signer=signer, config=config)
        self.discovery_wait_s = ros["discovery_wait_s"]

    def publish_iteration(self, rec: Mapping[str, Any]) -> None:
        """Publish one engine iteration record (the driver's callback dict)."""
        if self._iteration_pub.get_subscription_count() == 0:
            return  # a VOLATILE topic with no reader matched: nobody would receive it
        msg = IterationRecord()
        stamp(msg.header)
        self._seq += 1
        protocol.fill_iteration_record(msg, rec, self.run_id, self._seq)
        signer = self.evaluator.signer
        self._iteration_pub.publish(msg if signer is None else signer.sign_iteration(msg))  # signed: its bytes

    def wait_for_all_acked(self, wait_s: float, slice_s: float = 0.05,
                           give_up: Callable[[], bool] | None = None) -> bool:
        """Block until every reader (e.g. the recorder) acknowledged what we published.

        A RELIABLE sample that is not yet acknowledged is lost if its publisher goes away,
        so the coordinator waits for this before it shuts down. The wait is taken in short
        slices (other threads, the launcher's supervisor among them, keep running) and ends
        for a publisher as soon as it has no matched reader; a killed reader is unmatched
        once its participant's lease (12 s, bev_mdo's Fast DDS profile) expires, so it stalls
        the end of a run by at most that. Returns False (and logs which topics) after `wait_s`,
        or at once when `give_up()` says no reader that matters is alive (the launcher saw the
        recorder die: waiting for its lease to expire would only stall the end of the run).
        """
        pending = wait_acked([self._iteration_pub, *self.evaluator.request_publishers], wait_s, give_up, slice_s)
        if pending and not (give_up is not None and give_up()):
            self.get_logger().warning(f"not acknowledged within {wait_s:g} s on "
                                      f"{sorted(p.topic_name for p in pending)}")
        return not pending

    def _match_counts(self, own: OwnRecorder, topics) -> str:
        """What a recorder wait saw of this run's writers on `topics`, for its give-up line: per topic,
        the writers in the graph the recorder matched, and the readers in the graph our writer matched."""
        out = []
        for p in (self._iteration_pub, *self.evaluator.request_publishers):
            t = p.topic_name
            if t not in topics:
                continue
            writers = endpoints(self, t, p.msg_type, subscriber=False)
            readers = endpoints(self, t, p.msg_type)
            out.append(f"{t}: recorder matched {own.matched().get(t, 0)} of {len(writers)} writers, ours "
                       f"{p.get_subscription_count()} of {len(readers)} readers")
        return "; ".join(out)

    def wait_for_recorder(self, wait_s: float, binding: str | None = None, gone=None) -> OwnRecorder:
        """Wait until this run's own recorder, known by its declaration (this run id and, when
        given, `binding`; signed with the run's key when the run signs: recorder_node.OwnRecorder),
        reads every topic this run publishes and matched every publisher of it: the iteration and
        request topics (ours) and the result topics (this run's disciplines). Nobody else's
        subscriptions count. Waits while discovery makes progress (fastwait.until); ValueError once
        nothing changed for `wait_s`, or as soon as `gone()` says why the recorder's process ended."""
        own = OwnRecorder(self, self.run_id, self.evaluator.signer, binding)
        ev = self.evaluator
        # who must have been matched on each result topic: every accepted instance of this run (each
        # publishes on the result topic; a data-flow topic has its discipline's instances), not those
        # this process's graph happens to show yet, which may be fewer than the recorder must read
        writers = {RESULT_TOPIC: {i for v in ev.instances.values() for i in v}}
        for d, v in ev.instances.items():
            writers[mda_result_topic(d)] = set(v)

        def missing() -> list[str]:
            out = [p.topic_name for p in (self._iteration_pub, *ev.request_publishers)
                   if not own.records(p.topic_name, pub=p)]
            return out + [t for t in (RESULT_TOPIC, *ev.flow_readers())
                          if not (writers.get(t) and own.records(t, publishers=writers[t]))]

        def progress() -> tuple:
            return (json.dumps(own.declaration, sort_keys=True), tuple(sorted(own.dropped.items())),
                    ev.progress())

        ready = until(lambda: not missing() or bool(gone and gone()), wait_s, lambda: ev.spin(0.05), progress,
                      lambda: f"this run's recorder on {missing()}")
        if gone is not None and missing() and gone():  # no declaration is coming
            raise StartupGaveUp(f"the run's recorder {gone()}")
        if not ready:
            what = (f"declared itself but did not match {missing()} ({self._match_counts(own, missing())})" if own.declaration else
                    "did not declare itself" + (f" (dropped: {dict(own.dropped)})" if own.dropped else "")
                    + f" ({own.undeclared()})")
            raise StartupGaveUp(f"the run's recorder {what}; nothing changed for {wait_s:g} s")
        self.evaluator.dropped.update(own.dropped)
        return own


def run(config: Mapping[str, Any], *, run_id: str | None = None, formulation: str | None = None,
        optimizer: str | None = None, x0: Mapping[str, float] | None = None,
        on_iteration: Callable[[dict], None] | None = None, recorder_subscribers: int = 0,
        context=None, signer=None, instances: Mapping[str, int] | None = None,
        give_up_acks: Callable[[], bool] | None = None, beside=None, starts: int | list = 1, seed: int = 0,
        recorder_binding: str | None = None, starting: Callable[[], tuple] | None = None,
        before: Callable[[RosEvaluator], None] | None = None, recorder_gone: Callable[[], str | None] | None = None):
    """Run one optimisation over ROS in this process (rclpy must be initialised). Returns (result, node stats).
    ``beside``: a composed.Beside (discipline nodes in this process and `context`) to serve.
    ``recorder_subscribers``: 1 to wait for the run's own recorder (by its declaration; with
    ``recorder_binding``, the binding it must declare: binding.config_binding), 0 not to; not once
    ``recorder_gone()`` says why its process ended (sessions.recorder_gone).
    ``starting``: start-up progress of the run's processes (launcher.Launcher.progress), for the waits.
    ``before``: called with the evaluator once every discipline is there, before the recorder wait and
    the optimisation (the baseline, analysed as a sub-run through the same node: sessions.py)."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.driver import run_optimization

    config = RunConfig.of(config)
    run_id = run_id or uuid.uuid4().hex[:16]
    node = CoordinatorNode(config, run_id, signer=signer, context=context, node_name=node_name_for(run_id))
    node.evaluator.starting = starting
    if beside is not None:
        beside.attach(node.evaluator)
    try:
        names = list(config.names)
        node.evaluator.wait_for_disciplines(names, node.discovery_wait_s)
        twins = [n for n, _ in node.get_node_names_and_namespaces() if n == node.get_name()]
        if len(twins) > 1:  # by hand, -p run_id:= typed twice: each took the other's results (wrong answers)
            raise ValueError(f"another coordinator runs run id {run_id!r} on this ROS domain (node {node.get_name()}): "
                             "two runs of one run id take each other's results; give each its own -p run_id:=")
        for name, count in (instances or {}).items():  # a pool starts with all its instances (pool.py)
            if count > 1:
                node.evaluator.wait_for_instances(name, count, node.discovery_wait_s)
        if before is not None:
            before(node.evaluator)
        if recorder_subscribers:
            node.wait_for_recorder(node.discovery_wait_s, recorder_binding, recorder_gone)
        node.evaluator.warm_up(names)

        def callback(rec: dict) -> None:
            node.publish_iteration(rec)
            node.evaluator.iteration = int(rec["iteration"]) + 1  # records published so far
            if on_iteration is not None:
                on_iteration(rec)

        if starts != 1:  # --starts (a count, or a resumed multi-start's points): all through the same nodes, one bag
            from bev_mdo.mdo.multistart import run_starts

            result = run_starts(config.settings, node.evaluator, starts, seed=seed, formulation=formulation,
                                optimizer=optimizer, callback=callback)
        else:
            result = run_optimization(config.settings, node.evaluator, formulation=formulation,
                                      optimizer=optimizer, x0=x0, callback=callback)
        stats = {"run_id": node.run_id, "dropped": dict(node.evaluator.dropped), "retried": node.evaluator.retried,
                 "data_flow_mdas": node.evaluator.flows, "refused_instances": dict(node.evaluator.refused),
                 "t_optimised": time.monotonic(), "discipline_errors": dict(node.evaluator.first_errors),
                 "pools": node.evaluator.pool_summary(), "unresponsive": sorted(node.evaluator.unresponsive)}
        stats["all_acked"] = node.wait_for_all_acked(node.discovery_wait_s, give_up=give_up_acks)
        return result, stats
    except BaseException:  # SIGINT, SIGTERM, a failure: the records published so far reach the recorder first
        if recorder_subscribers:
            node.wait_for_all_acked(min(node.discovery_wait_s, 5.0), give_up=give_up_acks)
        raise
    finally:
        if beside is not None:
            beside.detach()
        teardown(lambda: (node.evaluator.close(), node.destroy_node()))  # bounded; in the CLI at exit, after the result


def main(args: list[str] | None = None) -> int:
    """`ros2 run bev_mdo coordinator_node --ros-args -p config:=... [-p formulation:=idf -p optimizer:=SLSQP]
    [-p recorders:=1 -p run_id:=RUN] [-p compose:=coordinator]` (with a recorder started on its own for
    the same run, ``recorder_node --run-id RUN``, wait for its declaration so the bag misses nothing; with compose:=coordinator the disciplines' nodes run in this process, composed.Beside)."""
    from bev_mdo.mdo.first_order import exit_status
    from bev_mdo.config import RunConfig
    from bev_mdo.ros.paths import default_config

    rclpy.init(args=args)
    beside = None
    try:
        probe = Node("coordinator_node")  # the params-file section it reads (coordinator_node:)
        p = {k: declare(probe, k, default, desc, whole_as_text=k == "instances") for k, default, desc in (
            ("config", "", "run config YAML"), ("formulation", "", "mdf | idf (default: config)"),
            ("optimizer", "", "optimizer name (default: config)"), ("run_id", "", "run id (default: random)"),
            ("recorders", 0, "1: before the first evaluation, wait for this run's recorder (recorder_node --run-id RUN)"),
            ("instances", "", "wait for pools before the first evaluation: N or name=N[,name=N] (as --instances)"),
            ("compose", "", "coordinator: serve every discipline (but pools) from nodes in this process (--compose)"))}
        check_parameters(probe._parameter_overrides, probe._parameters, probe.get_name())  # a misspelt -p: refused
        probe.destroy_node()
        config = RunConfig.load(p["config"] or default_config())
        _check_static(config, p)  # a mistake in them is said at once, not after the discovery wait
        instances = _instances(p["instances"], config)
        run_id = p["run_id"] or uuid.uuid4().hex[:16]
        local = beside_coordinator(p["compose"], list(config.names), instances)
        if local:
            from bev_mdo.ros.composed import Beside

            beside = Beside(config, local, rclpy.get_default_context(), run_id=run_id, instance=run_id[:8])
        result, stats = run(config, run_id=run_id, formulation=p["formulation"] or None,
                            optimizer=p["optimizer"] or None, recorder_subscribers=int(p["recorders"]),
                            instances=instances, beside=beside,
                            on_iteration=lambda r: print(f"iter {r['iteration']:4d}  objective {r['objective']:.6g}  max "
                                                         f"violation {r.get('max_violation', 0):.3g}", file=sys.stderr))
        print(jsontext.dumps({"result": result.to_dict(), **stats}))  # strict JSON: NaN as null
        return exit_status({**result.to_dict(), "unresponsive_disciplines": stats["unresponsive"]})  # optimize's
    except ValueError as exc:  # SIGINT, SIGTERM: raised on, ros/run.py says so in one line (exit 130, 143)
        print(f"coordinator_node: error: {exc}", file=sys.stderr)
        return STARTUP_GAVE_UP_STATUS if isinstance(exc, StartupGaveUp) else 2
    finally:
        if beside is not None:
            beside.close()
        if rclpy.ok():
            rclpy.shutdown()


def _check_static(config, p: Mapping[str, Any]) -> None:
    """ValueError naming a bad formulation, optimizer, recorders or compose parameter."""
    from bev_mdo.config import check_optimizer_options
    from bev_mdo.config.load import FORMULATIONS
    from bev_mdo.mdo.optimizers import canonical_name

    if p["formulation"] and p["formulation"].lower() not in FORMULATIONS:
        raise ValueError(f"formulation {p['formulation']!r} is unknown; allowed: {', '.join(FORMULATIONS)}")
    if p["optimizer"]:  # names the known optimizers, or the config's option the chosen one does not take
        check_optimizer_options(canonical_name(p["optimizer"]), config.settings.optimizer.options)
    if p["recorders"] not in (0, 1):
        raise ValueError(f"recorders must be 0 or 1 (wait for this run's recorder), got {p['recorders']}")
    if p["compose"] not in ("", "none", "coordinator"):
        raise ValueError(f"compose must be coordinator or none, got {p['compose']!r} (composed_node runs groups)")


def _instances(spec: str, config) -> dict[str, int] | None:
    """The ``instances`` parameter as {discipline: count} (None when empty)."""
    if not spec:
        return None
    from bev_mdo.processes import parse_instances

    return parse_instances(spec, discipline_names(config), flag="-p instances")
