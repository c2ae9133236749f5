"""A discipline call bounded in time, where the discipline runs in the caller's own thread.

The budget a ROS run gives a discipline before its points fail is ``ros.timeout_s`` x
(``ros.retries`` + 1). A transport that calls the discipline itself (the in-process evaluator,
api/failures.py; discipline nodes composed into the coordinator's process, ros/composed.py: Beside)
cannot wait for an answer while it computes one, so ``TimedDiscipline`` gives each compute() that
budget: one that does not return within it is interrupted (SIGALRM, main thread only, and only while
the caller has no ITIMER_REAL of its own running, which is left as it is; otherwise the call is not
bounded) and the discipline counts as hung for the rest of the run: its points fail at once with an
error naming it and the point, as a ROS node that never answers fails every request.
A discipline's ``prepare()``, its one-time work such as compiling a model, runs before the first
call, untimed. A SIGINT during a hung call still interrupts it (KeyboardInterrupt is not caught).
What a discipline prints in the main thread goes to stderr, as a node's goes to its log: stdout is the
command's output (a ``print`` in a user's compute came before the JSON of ``evaluate --json``).
"""
from __future__ import annotations

import contextlib
import signal
import sys
import threading
from typing import Any

from bev_mdo.mdo.discipline import prepare


class DisciplineTimeout(Exception):
    pass


class TimedDiscipline:
    """A discipline whose compute() is given at most `timeout_s` (see the module doc); ``prepared``:
    its prepare() was run already (a node's discipline)."""

    def __init__(self, disc: Any, timeout_s: float, prepared: bool = False):
        self._disc = disc
        self._timeout_s = float(timeout_s)
        self._hung = ""
        self._prepared = prepared

    def __getattr__(self, name):  # name, inputs, outputs, parameters, ... of the wrapped discipline
        return getattr(self._disc, name)

    @property
    def hung(self) -> bool:
        """True once a call overran the budget (every later call fails at once)."""
        return bool(self._hung)

    def prepare(self) -> None:
        """One-time work (e.g. compiling a model), once: not a hang, done before the clock starts."""
        if not self._prepared:
            self._prepared = True
            if threading.current_thread() is threading.main_thread():
                with contextlib.redirect_stdout(sys.stderr):
                    prepare(self._disc)
            else:
                prepare(self._disc)

    def compute(self, inputs):
        if self._hung:
            raise DisciplineTimeout(self._hung)
        self.prepare()
        if threading.current_thread() is not threading.main_thread():
            return self._disc.compute(inputs)  # (sys.stdout is the process's: not redirected beside other threads)
        if signal.getitimer(signal.ITIMER_REAL)[0] > 0:  # the caller's own timer runs: its alarm, not ours
            with contextlib.redirect_stdout(sys.stderr):
                return self._disc.compute(inputs)

        def alarm(*_):
            raise DisciplineTimeout(f"no answer within {self._timeout_s:g} s (ros.timeout_s x (ros.retries + 1), "
                                    "called in this process); the discipline is treated as hung")

        old = signal.signal(signal.SIGALRM, alarm)
        signal.setitimer(signal.ITIMER_REAL, self._timeout_s)
        try:
            with contextlib.redirect_stdout(sys.stderr):
                return self._disc.compute(inputs)
        except DisciplineTimeout as exc:
            self._hung = str(exc)
            raise
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)
