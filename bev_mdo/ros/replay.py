"""Replay a recorded bag: publish its messages (raw CDR) on their topics again.

Publishers use the generated Python class named by each schema; the recorded bytes are
published unchanged (``Publisher.publish(bytes)``). Timing is the recorded log time scaled
by ``rate``, or none at all (``rate=None``: as fast as possible). Messages go out in file
order, so per-topic order is kept; order across topics is not guaranteed by DDS, so use
the messages' ``sequence`` fields where global order matters.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import yaml
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from bev_mdo.bag.errors import BagError
from bev_mdo.bag.history import ITERATION_TOPIC, RecordOrder
from bev_mdo.bag.reader import Bag, BagMessage
from bev_mdo.ros.fastwait import until
from bev_mdo.ros.recorder_node import message_class

MAX_DEPTH = 100_000


@dataclass
class ReplayStats:
    """What a replay published and how long it took."""

    messages: int
    seconds: float
    truncated: bool

    @property
    def messages_per_s(self) -> float:
        return self.messages / self.seconds if self.seconds > 0 else float("inf")


def _qos(channel_metadata: dict, count: int) -> QoSProfile:
    """RELIABLE, KEEP_LAST deep enough for the whole topic (no silent overwrite when AFAP)."""
    durable = False
    try:
        for profile in yaml.safe_load(channel_metadata.get("offered_qos_profiles") or "[]") or []:
            durable |= str(profile.get("durability", "")).lower() in ("transient_local", "1")
    except yaml.YAMLError:
        pass
    return QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                      depth=max(10, min(count, MAX_DEPTH)),
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if durable
                      else DurabilityPolicy.VOLATILE)


class Replayer:
    """Publishers for the topics of one bag on a given node."""

    def __init__(self, node: Node, bag: Bag, topics: list[str] | None = None):
        from rclpy.executors import SingleThreadedExecutor

        self.node = node
        self.bag = bag
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(node)
        unknown = sorted(set(topics or []) - set(bag.topics))
        if unknown:
            raise BagError(f"{bag.mcap_path}: no topic {', '.join(unknown)} in this bag")
        # iteration records as every reader takes them: the bag's own run, each once, fresh and in order (all of
        self.order = RecordOrder(bag.info.get("run_id", ""), bag.stored_config.window_s, bounded=False)  # them held)
        self.messages: list[BagMessage] = [m for m in bag.messages(topics) if m.topic != ITERATION_TOPIC
                                           or self.order.keep(m.data, m.log_time_ns)]
        self.publishers = {}
        by_topic = {c.topic: c for c in bag.channels.values()}
        for topic in dict.fromkeys(m.topic for m in self.messages):
            type_name = bag.topics[topic]
            try:
                cls = message_class(type_name)
            except (ImportError, AttributeError) as exc:
                raise BagError(f"{bag.mcap_path}: no installed Python class for {type_name}") from exc
            self.publishers[topic] = node.create_publisher(
                cls, topic, _qos(by_topic[topic].metadata, bag.counts.get(topic, 0)))

    def wait_subscribers(self, count: int, timeout_s: float) -> bool:
        """Spin until every publisher has ``count`` subscriptions (False on timeout)."""
        return until(lambda: all(p.get_subscription_count() >= count for p in self.publishers.values()),
                     timeout_s, lambda: self._executor.spin_once(timeout_sec=0.05))

    def play(self, rate: float | None = 1.0) -> ReplayStats:
        """Publish every message once; ``rate=None`` publishes as fast as possible."""
        msgs = self.messages
        start = time.monotonic()
        t0 = msgs[0].log_time_ns if msgs else 0
        pubs = self.publishers
        for m in msgs:
            if rate:
                delay = start + (m.log_time_ns - t0) / 1e9 / rate - time.monotonic()
                if delay > 0:
                    time.sleep(delay)
            pubs[m.topic].publish(m.data)
        return ReplayStats(len(msgs), time.monotonic() - start, self.bag.truncated)

    def wait_acked(self, timeout_s: float = 10.0) -> bool:
        """Wait until subscribers acknowledged everything (RELIABLE), so exiting loses nothing."""
        return all(p.wait_for_all_acked(Duration(seconds=timeout_s)) for p in self.publishers.values())


def replay(path, *, rate: float | None = 1.0, topics: list[str] | None = None, loop: bool = False,
           wait_subscribers: int = 0, wait_timeout_s: float = 30.0, log=print) -> ReplayStats:
    """Open a bag, start rclpy, publish (repeatedly with ``loop``) and shut down."""
    import rclpy

    from bev_mdo.bag.reader import open_bag

    bag = open_bag(path)
    if bag.truncated:
        log(bag.recovery_note() + "; replaying the complete part")
    if rate is not None and rate <= 0:
        raise ValueError(f"--rate must be > 0, got {rate}")
    context = rclpy.context.Context()
    rclpy.init(context=context)
    node = Node("bev_mdo_replay", context=context)
    total = ReplayStats(0, 0.0, bag.truncated)
    try:
        player = Replayer(node, bag, topics)
        if player.order.note():
            log(f"{bag.mcap_path}: {player.order.note('not replaying')[2:]}")
        if wait_subscribers and not player.wait_subscribers(wait_subscribers, wait_timeout_s):
            short = [t for t, p in player.publishers.items() if p.get_subscription_count() < wait_subscribers]
            raise BagError(f"{bag.mcap_path}: fewer than {wait_subscribers} subscriber(s) on {', '.join(short)} after "
                           f"{wait_timeout_s:g} s (--no-wait publishes anyway)")
        while True:
            stats = player.play(rate)
            total.messages += stats.messages
            total.seconds += stats.seconds
            if not loop or not stats.messages:
                break
        player.wait_acked()
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)
    return total
