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


def now_ns() -> int:
    """Wall-clock time in ns since the epoch (what rosbag2 records)."""
    return time.time_ns()


def stamp(header, t_ns: int | None = None) -> None:
    """Set a std_msgs/Header stamp from ns since the epoch."""
    t_ns = now_ns() if t_ns is None else t_ns
    header.stamp.sec = t_ns // 1_000_000_000
    header.stamp.nanosec = t_ns % 1_000_000_000
