"""Restart a launched node whose process lives but whose DDS participant has gone silent.

A node can hang inside the middleware while its process stays alive (a Fast DDS 2.14 discovery
deadlock, eProsima/Fast-DDS#6502; docs/security.md, "A node that falls silent"); the launcher's
supervisor only sees processes that exit. This watchdog runs beside it, in the launching process,
with its own small participant, and reads the ROS graph every `period_s`. If a launched node was on
the graph and has been missing for `silent_s` (its lease expired), or has not appeared `start_s`
after its process started and used no CPU for `silent_s`, while its process still runs, the watchdog
sends SIGUSR1 (its stacks to its log, bev_mdo/stacks.py), SIGKILLs it and lets the supervisor
restart it; the node's ``hangs`` counter records it. A healthy node never leaves the graph, however
long it computes; if the watchdog's own participant hangs, its graph freezes and it does nothing.
"""
from __future__ import annotations

import contextlib
import signal
import sys
import threading
import time
from typing import Callable

SILENT_S = 7.0   # a node dropped by discovery (its 12 s lease over) and not back: 7 announcements missed
START_S = 45.0   # a node process that never reaches the graph (imports take ~20 s at load 40 here)


class HangWatchdog:
    """Watches a Launcher's nodes on the ROS graph (see the module docstring)."""

    def __init__(self, launcher, domain_id: int, *, period_s: float = 0.5, silent_s: float = SILENT_S,
                 start_s: float = START_S):
        self.launcher = launcher
        self.domain_id = domain_id
        self.period_s, self.silent_s, self.start_s = period_s, silent_s, start_s
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._ctx = self._node = None  # the watchdog's own ROS context and node (stop() destroys them)

    def start(self) -> "HangWatchdog":
        self._thread = threading.Thread(target=self._run, name="bev_mdo.watchdog", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 2.0) -> None:
        """Stop watching (before the launcher stops its nodes, which then leave the graph on purpose),
        then destroy the watchdog's participant in this thread, within stacks.deadline (in the `bev-mdo`
        process at its exit, after the result is printed: stacks.teardown). Left to the
        watching thread (a daemon), a teardown still running when the process exits meets Fast DDS's
        own destructors there: a participant being deleted waits for its discovery callbacks by
        busy-spinning (eProsima/Fast-DDS#6513: std::condition_variable on a glibc without
        pthread_cond_clockwait, as in the pip wheels), and the factory's destructor then waits on it
        for good. A watching thread that does not end (its participant hung in the middleware) is
        left; the process's exit is bounded (stacks.bound_exit)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=timeout_s)
            if self._thread.is_alive():
                return
        node, ctx, self._node, self._ctx = self._node, self._ctx, None, None
        if ctx is None:
            return
        import rclpy

        from bev_mdo.stacks import teardown

        def close():
            if node is not None:
                node.destroy_node()
            rclpy.shutdown(context=ctx)

        teardown(close)

    def _run(self) -> None:
        import os

        import rclpy

        self._ctx = ctx = rclpy.context.Context()
        rclpy.init(context=ctx, domain_id=self.domain_id)
        self._node = node = rclpy.create_node(f"launcher_watchdog_{os.getpid()}", context=ctx,
                                              enable_rosout=False, start_parameter_services=False)
        self._loop(lambda: set(node.get_node_names()))  # torn down by stop(), in the caller's thread

    def _loop(self, graph: Callable[[], set[str]]) -> None:
        while not self._stop.wait(self.period_s):
            try:
                names = graph()
            except Exception:  # noqa: BLE001 - a graph query racing the shutdown of the context
                return
            self.check(names, time.monotonic())

    def check(self, names: set[str], now: float) -> list[str]:
        """One look at the graph: kill the hung nodes (the supervisor restarts them); their labels."""
        hung = []
        with self.launcher._lock:
            if self._stop.is_set() or self.launcher._stopping.is_set():
                return hung
            for n in self.launcher.nodes:
                if not n.ros_names or n.proc is None or n.killed or n.proc.poll() is not None:  # killed: once
                    continue
                if all(name in names for name in n.ros_names):
                    n.seen, n.missing_since = True, None
                    continue
                if not n.restart:  # watched for Launcher.progress only (the recorder)
                    continue
                if n.seen:
                    n.missing_since = n.missing_since or now
                    if now - n.missing_since < self.silent_s:
                        continue
                    why = f"left the ROS graph {now - n.missing_since:.0f} s ago"
                elif now - n.spawned_at >= self.start_s and not n.busy(now, self.silent_s):
                    # still using CPU: still starting (imports take minutes with eight runs starting on 2 cores)
                    why = (f"has not appeared on the ROS graph {now - n.spawned_at:.0f} s after starting and "
                           f"used no CPU for {self.silent_s:g} s")
                else:
                    continue
                print(f"[launcher] {n.label} {why} while its process runs: a hung middleware (Fast DDS can "
                      f"deadlock, eProsima/Fast-DDS#6502); its stack is in its log; killed, to be restarted",
                      file=sys.stderr)
                with contextlib.suppress(ProcessLookupError):
                    n.proc.send_signal(signal.SIGUSR1)
                    time.sleep(0.3)  # the stack dump is written by the node's Python thread
                    n.proc.kill()
                n.hangs += 1
                n.seen, n.missing_since, n.killed = False, None, True  # recovering until its successor is spawned
                hung.append(n.label)
        return hung
