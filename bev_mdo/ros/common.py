"""Topic names and QoS shared by every bev_mdo node.

QoS is chosen on purpose: RELIABLE delivery with KEEP_LAST history deep enough that
nothing in flight is overwritten. A RELIABLE KEEP_LAST publisher does not block when a
subscriber lags; it silently overwrites the oldest sample, so depth must exceed the
number of messages a peer can have outstanding. The coordinator sends at most one
request per discipline per wave and waits for the wave, so a few messages per
discipline are in flight; the depths below leave two orders of magnitude of margin.
"""
from __future__ import annotations

import time
from typing import Callable, Iterable

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

PREFIX = "/bev_mdo"
RESULT_TOPIC = f"{PREFIX}/result"
ITERATION_TOPIC = f"{PREFIX}/iteration"
INFO_TOPIC = f"{PREFIX}/discipline_info"
MDA_REQUEST_TOPIC = f"{PREFIX}/mda_request"  # data flow: one request per feed-forward MDA, every node reads it


def request_topic(discipline: str) -> str:
    """Topic on which a discipline receives its evaluation requests."""
    return f"{PREFIX}/{discipline}/request"


def mda_result_topic(discipline: str) -> str:
    """Topic on which a discipline publishes its data-flow results (read by the disciplines
    that consume its outputs and by the coordinator)."""
    return f"{PREFIX}/{discipline}/mda_result"


REQUEST_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=256)
RESULT_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1024)
ITERATION_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1024)
# Data-flow results are TRANSIENT_LOCAL: a consumer whose subscription matches a producer a
# moment after the producer answered (discovery between two nodes is independent of what the
# coordinator sees) still gets the result. The depth is small because a whole batch is one
# message and an MDA has one result per discipline; 16 covers concurrent runs.
MDA_RESULT_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=16,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# Late joiners (a coordinator started after the disciplines) still get every declaration.
INFO_QOS = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=64,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)
# Declaration readers (disciplines', recorders'): a history is one queue for all writers, each declares once
DECLARATION_READER_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1024,
                                    durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Each node's request counters as JSON (std_msgs/String), so tests and operators can see
# what was received, answered and rejected (by reason) without reading logs.
# TRANSIENT_LOCAL depth 1: a late subscriber gets every node's latest counters.
NODE_STATS_TOPIC = f"{PREFIX}/node_stats"
NODE_STATS_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1,
                            durability=DurabilityPolicy.TRANSIENT_LOCAL)
# Readers keep more: samples of every node can arrive at once (a late joiner gets all of them).
NODE_STATS_READER_QOS = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST,
                                   depth=256, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def now_ns() -> int:
    """Wall-clock time in ns since the epoch (what rosbag2 records)."""
    return time.time_ns()


def stamp(header, t_ns: int | None = None) -> None:
    """Set a std_msgs/Header stamp from ns since the epoch."""
    t_ns = now_ns() if t_ns is None else t_ns
    header.stamp.sec = t_ns // 1_000_000_000
    header.stamp.nanosec = t_ns % 1_000_000_000


def wait_acked(publishers: Iterable, wait_s: float, give_up: Callable[[], bool] | None = None,
               slice_s: float = 0.05) -> list:
    """Wait until every reader acknowledged what each publisher sent; returns the publishers still
    waiting (empty: all acknowledged). A RELIABLE sample that is not acknowledged is lost if its
    publisher goes away. The wait is taken in ``slice_s`` slices (other threads keep running), ends
    for a publisher as soon as it has no matched reader, and stops after ``wait_s`` or at once when
    ``give_up()`` says no reader that matters is alive (a killed reader stays matched until its lease
    expires)."""
    from rclpy.duration import Duration

    pending = list(publishers)
    deadline = time.monotonic() + wait_s
    while pending:
        pending = [p for p in pending if p.get_subscription_count() > 0
                   and not p.wait_for_all_acked(Duration(nanoseconds=int(slice_s * 1e9)))]
        if pending and ((give_up is not None and give_up()) or time.monotonic() > deadline):
            break
    return pending


def node_of(info) -> str:
    """The node of a graph endpoint (TopicEndpointInfo) as ``namespace/name``, without the leading ``/``."""
    return f"{info.node_namespace.rstrip('/')}/{info.node_name}".lstrip("/")


def type_name(msg_type) -> str:
    """``package/msg/Name`` of a message class (or that string itself), as the graph names a topic's type."""
    if isinstance(msg_type, str):
        return msg_type
    return f"{msg_type.__module__.split('.')[0]}/msg/{msg_type.__name__}"


def run_type(topic: str) -> str | None:
    """The message type this project's nodes use on `topic` (None: not one of its topics)."""
    if not topic.startswith(PREFIX + "/"):
        return None
    last = topic.rsplit("/", 1)[-1]
    named = {"iteration": "IterationRecord", "result": "EvaluationResult", "mda_result": "EvaluationResult",
             "request": "EvaluationRequest", "mda_request": "EvaluationRequest", "discipline_info": "DisciplineInfo",
             "pareto_front": "ParetoFront"}
    if last == "node_stats":
        return "std_msgs/msg/String"
    return f"bev_mdo_msgs/msg/{named[last]}" if last in named else None


_SQUATTERS: set[tuple[str, bool]] = set()  # (node, reads) of the squatters this process has named


def endpoints(node, topic: str, msg_type, subscriber: bool = True, warn: bool = False) -> list:
    """The readers (``subscriber``) or writers of `topic` in the graph that use the type `msg_type`.

    An endpoint of another type (a process squatting on the run's topic) never matches ours: DDS
    matches only endpoints of one type, so it neither receives nor sends this run's messages. It is
    left out (a count of all endpoints would wait for it forever) and, with ``warn``, the first topic
    a squatting node is found on is named in one line on stderr, once per process."""
    import sys

    want = type_name(msg_type)
    infos = node.get_subscriptions_info_by_topic(topic) if subscriber else node.get_publishers_info_by_topic(topic)
    same = []
    for info in infos:
        if info.topic_type == want:
            same.append(info)
        elif warn and (key := (node_of(info), subscriber)) not in _SQUATTERS:
            _SQUATTERS.add(key)
            print(f"warning: node '{key[0]}' {'reads' if subscriber else 'publishes on'} {topic} as "
                  f"{info.topic_type}, not {want}: it cannot exchange messages with this run (ignored)",
                  file=sys.stderr, flush=True)
    return same


def declare(node, name: str, default, description: str = "", whole_as_text: bool = False):
    """The value of parameter `name` of `node`, declared with `default` (its type) and `description`. A
    value of another type (``-p``, a parameters file) is a ValueError naming the parameter, the value, its
    type and the type expected, not rclpy's traceback; a whole number for a DOUBLE is that number (and
    with `whole_as_text`, for a STRING its digits: ``instances:=2``)."""
    from rcl_interfaces.msg import ParameterDescriptor
    from rclpy.parameter import Parameter

    desc = ParameterDescriptor(description=description, dynamic_typing=True)  # the type is checked here
    value = node.declare_parameter(name, default, desc).value
    kind, want = (Parameter.Type.from_parameter_value(v).name for v in (value, default))
    if kind == want:
        return value
    if (kind, want) == ("INTEGER", "DOUBLE") or (kind, want, whole_as_text) == ("INTEGER", "STRING", True):
        return float(value) if want == "DOUBLE" else str(value)
    quote = f" (quote it: -p \"{name}:='{value}'\")" if want == "STRING" and kind in ("INTEGER", "DOUBLE", "BOOL") else ""
    shown = list(value) if kind.endswith("_ARRAY") else value
    raise ValueError(f"parameter {name}: {shown!r} is {kind}, expected {want}{quote}")

