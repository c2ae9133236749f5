"""``recorder_node``: raw subscriptions written unchanged (CDR) to a rosbag2-compatible MCAP bag.

Records a given topic list, or every topic under ``/bev_mdo/`` found by polling the graph,
so it can record any running suite. SIGINT/SIGTERM close the bag cleanly; after a SIGKILL the bag
holds every chunk closed (after each iteration record, and every ``flush_period_s``): ``bag repair``.

Parameters: ``bag_path`` (default ``bags/<time>_record``), ``topics`` (string[]; empty: all
under ``prefix``), ``prefix`` (``/bev_mdo/``), ``config_file`` (stored as ``config_yaml``, its relative
paths made absolute: config.load.recorded_text), ``config_yaml`` (text, instead of a file), ``run_id``, ``qos_depth``
(10000), ``discovery_period_s`` (0.5), ``flush_period_s`` (1.0), ``status_period_s`` (0.05), ``nice``
(10: the recorder runs at a lower CPU priority than the nodes and the coordinator).

With a ``run_id`` it records that run and its sub-runs only. Whenever it changes, it declares on
``/bev_mdo_recorder/status`` (TRANSIENT_LOCAL, not recorded; signed with the run's key when it has
one) ``{"declaration": JSON text, "signature": hex}``, the text ``{"run_id", "binding", "recorder",
"bag", "matched": {topic: matched publishers}, "publishers": {topic: [node names it matched]}}``
(``binding``: ``binding.config_binding`` of the config it stores). Iteration records: verified with the run's key,
once and in order (an unsigned run's too); with no config, so no key, as received, left to the readers
(``bag.order.RecordOrder``). What is dropped
and counted, how a coordinator waits for its recorder: docs/recording.md, "Whose bag: the run's own recorder".
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from pathlib import Path

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from bev_mdo import interrupts
from bev_mdo.bag.history import ITERATION_TOPIC, RecordOrder
from bev_mdo.bag.stored import StoredConfig
from bev_mdo.bag.writer import BagWriter
from bev_mdo.binding import config_binding, run_matches
from bev_mdo.config.load import recorded_text
from bev_mdo.processes import check_parameters
from bev_mdo.protocol.messages import RUN_TAGGED, run_of, stats_run_of
from bev_mdo.ros.common import DECLARATION_READER_QOS, NODE_STATS_TOPIC, declare, endpoints, node_of, run_type

DEFAULT_PREFIX = "/bev_mdo/"
RECHECK_S = 0.5  # the declared publishers of a topic are read from the graph at least this often
STATUS_TOPIC = "/bev_mdo_recorder/status"  # outside the prefix: the status is not recorded
STATUS_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1,
                        durability=DurabilityPolicy.TRANSIENT_LOCAL)


def message_class(type_name: str):
    """The generated Python class of ``pkg/msg/Type`` (ImportError/AttributeError if absent)."""
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def run_reader(topic: str, type_name: str):
    """How a run's recorder reads the run id of a message on `topic` from its bytes, to keep its own run's only
    (None: declarations, recorded as they are): after the header of a RUN_TAGGED type, or in a node's counters."""
    return run_of if type_name in RUN_TAGGED else stats_run_of if topic == NODE_STATS_TOPIC else None


def default_bag_path() -> str:
    return str(Path("bags") / time.strftime("%Y%m%d-%H%M%S_record"))


class RecorderNode(Node):
    """Subscribes raw to the wanted topics and writes every message to a BagWriter."""

    def __init__(self, *, writer: BagWriter | None = None, node_name: str = "recorder_node",
                 **kwargs):
        super().__init__(node_name, **kwargs)
        def p(name, default):  # a value of the wrong type is one line (ValueError), not rclpy's traceback
            return declare(self, name, default)

        self.bag_path = p("bag_path", default_bag_path())
        self.wanted = [t for t in p("topics", [""]) if t]
        self.prefix = p("prefix", DEFAULT_PREFIX)
        config_file = p("config_file", "")
        config_yaml = p("config_yaml", "")
        run_id = p("run_id", "")
        self.qos_depth = int(p("qos_depth", 10000))
        discovery_period_s = float(p("discovery_period_s", 0.5))
        flush_period_s = float(p("flush_period_s", 1.0))
        status_period_s = float(p("status_period_s", 0.05))
        self.nice = int(p("nice", 10))
        check_parameters(self._parameter_overrides, self._parameters, self.get_name())  # before the bag exists
        if config_file and not config_yaml:  # its relative paths made absolute, as the nodes read them
            config_yaml = recorded_text(config_file)
        self.binding = config_binding(config_yaml) if config_yaml else ""
        self.signer = _signer_of(config_yaml, Path(config_file).parent if config_file else Path.cwd())
        self.other_run = 0  # messages of other runs, not recorded
        self._confirmed: dict[str, tuple] = {}  # topic -> (counts seen, publisher names matched, when)
        meta = {"run_id": run_id, "recorder": self.get_fully_qualified_name()}
        if config_yaml:
            meta["config_yaml"] = config_yaml
        self.writer = writer or BagWriter(self.bag_path, metadata=meta)
        self.subscriptions_by_topic: dict[str, object] = {}
        self._handlers: dict[str, object] = {}
        self.received = 0
        self.run_id = run_id
        verify = self.signer.verify_iteration if self.signer is not None else None  # no config, so no key (records
        self.order = RecordOrder(run_id, StoredConfig.parse(config_yaml).window_s, verify,  # perhaps signed): kept
                                 ordered=bool(verify or config_yaml))  # as received; an unsigned run's: in order
        from std_msgs.msg import String

        self._status_pub = self.create_publisher(String, STATUS_TOPIC, STATUS_QOS)
        self._status = None
        self.discover()
        self.create_timer(discovery_period_s, self.discover)
        if status_period_s > 0:
            self.create_timer(status_period_s, self.publish_status)
        if flush_period_s > 0:
            self.create_timer(flush_period_s, self.writer.flush)
        self.get_logger().info(f"recording to {self.writer.path}")

    def _wants(self, topic: str) -> bool:
        return topic in self.wanted if self.wanted else topic.startswith(self.prefix)

    def discover(self) -> None:
        """Subscribe to every wanted topic that has appeared since the last poll."""
        for topic, types in self.get_topic_names_and_types():
            if topic in self.subscriptions_by_topic or not self._wants(topic) or not types:
                continue
            # a topic of this project is recorded with its own type, once a publisher of it is there: a
            # squatter publishing another type on the topic (even before the run's) does not choose it
            type_name = run_type(topic) or types[0]
            if type_name not in types:
                continue
            try:
                cls = message_class(type_name)
            except (ImportError, AttributeError, ValueError):
                self.get_logger().warning(f"skipping {topic}: no Python class for {type_name}")
                continue
            pubs = endpoints(self, topic, type_name, subscriber=False)
            if not pubs:
                # Only readers known so far (the graph can show a reader before its writer): our
                # durability must follow the publishers', or a VOLATILE reader of a TRANSIENT_LOCAL
                # topic loses what was published before the writer matched it. Next poll.
                continue
            transient = any(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in pubs)
            # Deep KEEP_LAST history: a RELIABLE KEEP_LAST publisher does not wait for a slow
            # subscriber, it silently overwrites the oldest unacknowledged sample. The depth
            # must cover every message that can pile up while this node is writing a chunk.
            qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                             depth=self.qos_depth,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL if transient
                             else DurabilityPolicy.VOLATILE)
            self.writer.add_topic(topic, type_name, [i.qos_profile for i in pubs],
                                  type_hash=_hash_of(pubs))
            self._handlers[topic] = self._callback(topic, type_name)
            self.subscriptions_by_topic[topic] = self.create_subscription(
                cls, topic, self._handlers[topic], qos, raw=True)
            self.get_logger().info(f"recording {topic} [{type_name}]")

    def _publishers_matched(self, topic: str, sub) -> list[str]:
        """Node names of the publishers of `topic` this recorder's subscription matched: all those in
        the graph once it matched as many as the graph shows, and those confirmed before that are
        still there (a newcomer is confirmed at the next full match)."""
        count, graph, now = sub.get_publisher_count(), self.count_publishers(topic), time.monotonic()
        seen, names, at = self._confirmed.get(topic, ((-1, -1), [], 0.0))
        # the counts alone can stay the same while one publisher replaces another (a run's baseline
        # coordinator, then its coordinator): the names are read again at least every RECHECK_S
        if (count, graph) != seen or now - at >= RECHECK_S:
            infos = endpoints(self, topic, sub.msg_type, subscriber=False)  # those that can match
            present = sorted({f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos})
            names = present if count >= len(infos) else [n for n in names if n in present]
            self._confirmed[topic] = ((count, graph), names, now)
        return names

    def publish_status(self) -> None:
        """Publish the declaration (see the module doc) if what it says changed."""
        from std_msgs.msg import String

        matched = {t: sub.get_publisher_count() for t, sub in self.subscriptions_by_topic.items()}
        publishers = {t: self._publishers_matched(t, sub) for t, sub in self.subscriptions_by_topic.items()}
        if (matched, publishers) != self._status:
            self._status = (matched, publishers)
            text = json.dumps({"run_id": self.run_id, "binding": self.binding, "bag": str(self.bag_path),
                               "recorder": self.get_fully_qualified_name(), "matched": matched,
                               "publishers": publishers}, sort_keys=True)
            sig = self.signer.sign_declaration(text) if self.signer is not None else ""
            self._status_pub.publish(String(data=json.dumps({"declaration": text, "signature": sig})))

    def _callback(self, topic: str, type_name: str):
        write = self.writer.write
        own = self.run_id
        run_in = run_reader(topic, type_name) if own else None
        order = self.order if topic == ITERATION_TOPIC else None

        def on_message(data: bytes, info) -> None:
            if run_in is not None:
                run = run_in(data)
                if run is None or not run_matches(own, run):
                    self.other_run += 1
                    return
            received = info.get("received_timestamp") or time.time_ns()
            if order is not None and not order.keep(data, received):
                return  # unsigned or forged, expired, a duplicate or a record from the past (counted)
            published = info.get("source_timestamp") or received
            write(topic, data, received, published, info.get("publication_sequence_number") or 0)
            self.received += 1
            if order is not None:  # one chunk per iteration record, as the in-process writer: a SIGKILL (or a
                self.writer.flush()  # flush timer starved on a busy host) keeps every iteration recorded

        return on_message

    def handlers(self) -> list:
        """(subscription, handler(data, info)) of every recorded topic."""
        return [(sub, self._handlers[t]) for t, sub in self.subscriptions_by_topic.items()]

    def drain(self, quiet_s: float = 0.05, max_s: float = 10.0) -> None:
        """Take what is still queued until nothing arrives for `quiet_s` (bounded by `max_s`)."""
        from bev_mdo.ros.fastwait import MultiWaiter

        waiter = MultiWaiter(self.context)
        deadline = time.monotonic() + max_s
        while time.monotonic() < deadline and self.context.ok():
            pairs = self.handlers()
            if waiter.take_all(pairs) == 0 and not (pairs and waiter.wait([s for s, _ in pairs], quiet_s)):
                return

    def close(self) -> None:
        """Write summary and metadata.yaml."""
        self.writer.close()


class OwnRecorder:
    """A run's own recorder as a node of the run sees it: known by its declaration (run id, binding,
    signed with the run's key when the run signs), never by a count of subscribers, which another
    run's recorder or any process on the domain adds to. Declarations of other runs, other bindings
    and unsigned or forged ones are dropped and counted (``dropped``)."""

    def __init__(self, node: Node, run_id: str, signer=None, binding: str | None = None):
        from collections import Counter

        from std_msgs.msg import String

        self.node, self.run_id, self.signer, self.binding = node, run_id, signer, binding
        self.declaration: dict | None = None
        self.dropped: Counter[str] = Counter()
        self._sub = node.create_subscription(String, STATUS_TOPIC, self._on_status, DECLARATION_READER_QOS)

    def _on_status(self, msg) -> None:
        try:
            outer = json.loads(msg.data)
            text, sig = outer["declaration"], outer.get("signature", "")
            decl = json.loads(text)
            run = decl["run_id"]
        except (ValueError, KeyError, TypeError):
            self.dropped["recorder_malformed"] += 1
            return
        if not run or not run_matches(run, self.run_id):
            self.dropped["recorder_other_run"] += 1
            return
        if self.signer is not None:
            why = self.signer.verify_declaration(text, sig)
            if why is not None:
                self.dropped[f"recorder_{why}"] += 1
                return
        if self.binding is not None and decl.get("binding") != self.binding:
            self.dropped["recorder_other_binding"] += 1
            return
        self.declaration = decl

    def undeclared(self) -> str:
        """What a node waiting for a declaration that never came sees, for its give-up line: how many
        writers of the recorders' status topic in the graph its reader matched, and whether a recorder
        of this run (named ``recorder_<run id>``) is on its ROS graph at all."""
        from std_msgs.msg import String

        writers = endpoints(self.node, STATUS_TOPIC, String, subscriber=False)
        here = any(n.startswith("recorder_") and self.run_id[:16] in n for n in self.node.get_node_names())
        return (f"its status topic: our reader matched {self._sub.get_publisher_count()} of {len(writers)} writers; "
                f"this run's recorder is {'' if here else 'not '}on this process's ROS graph")

    @property
    def name(self) -> str | None:
        return (self.declaration or {}).get("recorder")

    def matched(self) -> dict[str, int]:
        """{topic: publishers} the declared recorder matched ({} before it declared itself)."""
        return dict((self.declaration or {}).get("matched") or {})

    def records(self, topic: str, pub=None, publishers=()) -> bool:
        """Whether the declared recorder records what we need of `topic`: with our publisher `pub`,
        the recorder reads the topic, `pub` matched every reader of it in the graph and the recorder
        matched this node's publisher; with `publishers` (node names), it matched each of them."""
        d = self.declaration
        if d is None:
            return False
        declared = {n.lstrip("/") for n in (d.get("publishers") or {}).get(topic, ())}
        need = {n.lstrip("/") for n in publishers}
        if pub is not None:
            readers = endpoints(self.node, topic, pub.msg_type, warn=True)  # a squatter never matches
            names = {node_of(i) for i in readers}
            if str(self.name).lstrip("/") not in names or pub.get_subscription_count() < len(readers):
                return False
            need.add(self.node.get_fully_qualified_name().lstrip("/"))
        return need <= declared


def serve_until(node: "RecorderNode", stopped, idle_s: float = 0.05, timers_every_s: float = 0.02,
                nice: int = 0) -> None:
    """Record until stopped(): messages are taken straight from the subscriptions that the wait
    set found ready (fastwait); the node's own executor runs the timers (topic discovery, flush,
    status) at most every ``timers_every_s``, not once per message (an executor spin rebuilds a
    wait set over every entity and costs more than recording the message). With ``nice`` > 0 the
    process lowers its priority by that much once it recorded its first message."""
    from rclpy.executors import SingleThreadedExecutor

    from bev_mdo.ros.fastwait import MultiWaiter

    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    waiter = MultiWaiter(node.context)
    next_timers = 0.0
    try:
        while not stopped() and rclpy.ok(context=node.context):
            pairs = node.handlers()
            if pairs and waiter.wait([s for s, _ in pairs], idle_s):
                waiter.take_ready(pairs)
                if nice > 0 and node.writer.message_count:
                    os.nice(nice)
                    nice = 0
            now = time.monotonic()
            if now >= next_timers or not pairs:
                executor.spin_once(timeout_sec=0.0 if pairs else idle_s)
                next_timers = now + timers_every_s
    finally:
        executor.remove_node(node)
        executor.shutdown()


def _signer_of(config_yaml: str, base: Path):
    """The run's Signer from the stored config's ``ros.sign_key_file`` (None: not signing); a relative path
    from ``base``, the config file's folder, as every node reads it (it was read from the working directory)."""
    import yaml

    from bev_mdo.protocol.signing import Signer

    ros = (yaml.safe_load(config_yaml or "{}") or {}).get("ros") or {}
    key = ros.get("sign_key_file")
    return Signer.from_ros({**ros, "sign_key_file": str(base / Path(key).expanduser())}) if key else None


def _hash_of(pubs) -> str | None:
    for info in pubs:
        h = getattr(info, "topic_type_hash", None)
        if h is not None and getattr(h, "value", None):
            return f"RIHS{int(h.version):02d}_{bytes(h.value).hex()}"
    return None


def parse_args(argv: list[str]) -> tuple[argparse.Namespace, list[str]]:
    parser = argparse.ArgumentParser(prog="recorder_node", description=__doc__.splitlines()[0])
    parser.add_argument("--output", "-o", help="bag directory (default bags/<time>_record)")
    parser.add_argument("--topics", nargs="+", help="topics to record (default: all under /bev_mdo/)")
    parser.add_argument("--config", help="configuration file stored in the bag")
    parser.add_argument("--run-id", help="run id stored in the bag")
    return parser.parse_known_args(argv)


def main(args: list[str] | None = None) -> int:
    """Run the recorder until SIGINT/SIGTERM; returns the exit status."""
    from rclpy.parameter import Parameter
    from rclpy.signals import SignalHandlerOptions
    from rclpy.utilities import remove_ros_args

    argv = sys.argv[1:] if args is None else list(args)
    ns, _rest = parse_args(remove_ros_args(["recorder_node", *argv])[1:])
    overrides = []
    if ns.output:
        overrides.append(Parameter("bag_path", Parameter.Type.STRING, ns.output))
    if ns.topics:
        overrides.append(Parameter("topics", Parameter.Type.STRING_ARRAY, ns.topics))
    if ns.config:
        overrides.append(Parameter("config_file", Parameter.Type.STRING, ns.config))
    if ns.run_id:
        overrides.append(Parameter("run_id", Parameter.Type.STRING, ns.run_id))
    rclpy.init(args=["recorder_node", *argv], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        # SIGINT and SIGTERM (interrupts: installed by ros/run.py or the CLI) end the recording, as Ctrl-C ends
        # `ros2 bag record`: taken once the bag is closed (a second one too), then status 0; the closing line says
        # what the bag holds. One that lands while the node is still being made: one line, exit 130 (143), ros/run.py
        try:
            with interrupts.deferred():
                try:
                    node = RecorderNode(parameter_overrides=overrides)
                except ValueError as exc:
                    print(f"recorder_node: error: {exc}", file=sys.stderr)
                    return 2
                # The recorder yields the CPU to the run it records (on a 2-core host it otherwise adds
                # ~10 % to the MDA latency) once the run's first message arrived; through start-up (discovery,
                # matching, its declaration, which the run waits for) it keeps the priority of the run's other
                # processes, else a host loaded by many runs starting together starves it. Its subscription
                # queues are deep, so it catches up in the gaps, and it drains what is queued before it closes the bag.
                try:
                    serve_until(node, interrupts.pending, nice=node.nice)
                    node.drain()  # what already arrived, so a stop does not lose the run's tail
                finally:
                    node.close()
                    print(f"recorded {node.writer.message_count} messages to {node.writer.path}"
                          + (f"; {node.other_run} of other runs not recorded" if node.other_run else "")
                          + node.order.note() + node.order.none_note(), file=sys.stderr)
        except KeyboardInterrupt:  # SIGINT, or SIGTERM (interrupts.Terminated)
            if node is None:
                raise
        return 0
    finally:
        from bev_mdo.stacks import deadline

        with deadline():  # the bag is closed above; a teardown hung in Fast DDS must not outlive the run
            if node is not None:
                node.destroy_node()
            if rclpy.ok():
                rclpy.shutdown()


if __name__ == "__main__":
    sys.exit(interrupts.run_main("recorder_node", main))
