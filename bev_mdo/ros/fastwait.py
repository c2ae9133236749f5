"""Waiting: a lean wait on subscriptions for the hot path of an evaluation, and ``until``, the
one "wait until matched or deadline" loop of ros/ (graph matching, discovery, readiness).

rclpy's executors rebuild a wait set over every entity of a node (parameter
services included) and dispatch through coroutines on each `spin_once`; measured
here that is about 1 ms per call, several times the DDS round trip. This waits on
the hot subscriptions with one rcl wait set and takes messages directly, the way
`rclpy.wait_for_message` does. Everything else of the node is still spun by its
executor when idle.
"""
from __future__ import annotations

import sys
import time
from typing import Callable, Hashable

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

STARTUP_CAP = 10      # a start-up wait ends after this many times its no-progress bound, progress or not
SHOW_AFTER_S = 2.0    # a start-up wait says what it waits for once it took this long
SHOW_EVERY_S = 2.0


def until(ready: Callable[[], object], wait_s: float, step: Callable[[], object],
          progress: Callable[[], Hashable] | None = None, what: str | Callable[[], str] = "") -> bool:
    """Call `step()` (spin once, poll the graph, sleep) until `ready()` is true.

    Without `progress`: False once `wait_s` seconds passed without it (the caller says what was missing).
    With `progress` (a start-up wait): `wait_s` bounds the time WITHOUT PROGRESS, not the wait. The
    wait goes on as long as `progress()` (nodes seen, matches, declarations, probe answers) keeps
    changing, so a host loaded by many runs starting together is waited for, and it gives up only
    after `wait_s` seconds in which nothing changed, or after STARTUP_CAP x `wait_s` in all (a domain
    whose graph never settles). With `what` it shows, after SHOW_AFTER_S, one line on stderr every
    SHOW_EVERY_S: what it waits for and the seconds left before it gives up."""
    start = last = shown = time.monotonic()
    state = progress() if progress is not None else None
    while not ready():
        now = time.monotonic()
        if progress is not None:
            s = progress()
            if s != state:
                state, last = s, now
            if now - start > STARTUP_CAP * wait_s:
                return False
        if now - last > wait_s:
            return False
        if what and now - start >= SHOW_AFTER_S and now - shown >= SHOW_EVERY_S:
            shown = now
            print(f"[start-up] waiting for {what() if callable(what) else what}; gives up in "
                  f"{max(0.0, wait_s - (now - last)):.0f} s without progress", file=sys.stderr, flush=True)
        step()
    return True


class MultiWaiter:
    """The lean path of the hot subscriptions (the coordinator's results, a node's or a composed
    process's, the recorder's): messages taken from one rcl wait set, without an executor. The rcl handle of each subscription is
    looked up once (rclpy's ``handle`` property costs a Python call per use, several per message)."""

    def __init__(self, context):
        self._context = context
        self._ws = None
        self._n = -1
        self.ready: set[int] = set()
        self._info: dict[int, tuple] = {}   # id(subscription) -> (subscription, rcl handle, its pointer)

    def _of(self, sub) -> tuple:
        got = self._info.get(id(sub))
        if got is None or got[0] is not sub:
            h = sub.handle
            got = self._info[id(sub)] = (sub, h, h.pointer)
        return got

    def take_all(self, subs_and_handlers) -> int:
        """Take every pending message of each (subscription, handler(msg, info)); returns how many."""
        n = 0
        for sub, handle in subs_and_handlers:
            h = self._of(sub)[1]
            msg_type, raw = sub.msg_type, sub.raw
            while True:
                with h:
                    got = h.take_message(msg_type, raw)
                if got is None:
                    break
                handle(*got)
                n += 1
        return n

    def wait(self, subs, timeout_s: float) -> bool:
        """Block until one of `subs` has a message or `timeout_s` passes."""
        if len(subs) != self._n:
            self._ws = _rclpy.WaitSet(len(subs), 0, 0, 0, 0, 0, self._context.handle)
            self._n = len(subs)
        ws = self._ws
        ws.clear_entities()
        for s in subs:
            h = self._of(s)[1]
            with h:
                ws.add_subscription(h)
        ws.wait(max(0, int(timeout_s * 1e9)))
        self.ready = set(ws.get_ready_entities("subscription"))
        return bool(self.ready)

    def take_ready(self, subs_and_handlers) -> int:
        """Like take_all, but only from the subscriptions the last wait() found ready."""
        ready = self.ready
        return self.take_all([(s, h) for s, h in subs_and_handlers if self._of(s)[2] in ready])
