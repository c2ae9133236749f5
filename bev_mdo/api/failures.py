"""Failures named where the user looks, for the in-process transport.

- ``FirstErrors``: the first error of each failing discipline, printed once to the console.
- ``TimedDiscipline``: the in-process transport's timeout, the same budget a ROS run gives a
  discipline before its points fail (``ros.timeout_s`` x (``ros.retries`` + 1)). A compute() that
  does not return within it is interrupted (SIGALRM, main thread only; a discipline's ``prepare()``, its
  one-time work such as compiling a model, runs before the first call, untimed) and the discipline counts
  as hung for the rest of the run: its points fail at once with an error naming it, as a ROS node
  that never answers fails every request.
- ``NamingInProcessEvaluator``: the in-process evaluator reporting first errors.
"""
from __future__ import annotations

import signal
import sys
import threading
from typing import Any

from bev_mdo.mdo.discipline import first_error_line, prepare
from bev_mdo.mdo.evaluator import InProcessEvaluator


class FirstErrors:
    """Remembers (and prints once) the first error of each discipline."""

    def __init__(self):
        self.first: dict[str, str] = {}

    def note(self, discipline: str, error: str) -> None:
        if not error or discipline in self.first:
            return
        line = first_error_line(error)
        self.first[discipline] = line
        print(f"discipline {discipline!r} failed: {line}", file=sys.stderr, flush=True)


class DisciplineTimeout(Exception):
    pass


class TimedDiscipline:
    """A discipline whose compute() is given at most `timeout_s` (see the module doc)."""

    def __init__(self, disc: Any, timeout_s: float):
        self._disc = disc
        self._timeout_s = float(timeout_s)
        self._hung = ""
        self._prepared = False

    def __getattr__(self, name):  # name, inputs, outputs, parameters, ... of the wrapped discipline
        return getattr(self._disc, name)

    def prepare(self) -> None:
        """One-time work (e.g. compiling a model), once: not a hang, done before the clock starts."""
        if not self._prepared:
            self._prepared = True
            prepare(self._disc)

    def compute(self, inputs):
        if self._hung:
            raise DisciplineTimeout(self._hung)
        self.prepare()
        if threading.current_thread() is not threading.main_thread():
            return self._disc.compute(inputs)

        def alarm(*_):
            raise DisciplineTimeout(f"no answer within {self._timeout_s:g} s (in-process timeout: "
                                    "ros.timeout_s x (ros.retries + 1)); the discipline is treated as hung")

        old = signal.signal(signal.SIGALRM, alarm)
        signal.setitimer(signal.ITIMER_REAL, self._timeout_s)
        try:
            return self._disc.compute(inputs)
        except DisciplineTimeout as exc:
            self._hung = str(exc)
            raise
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, old)


class NamingInProcessEvaluator(InProcessEvaluator):
    """In-process evaluator with a timeout per discipline call and first errors named on the console."""

    def __init__(self, disciplines, timeout_s: float | None = None, errors: FirstErrors | None = None):
        discs = list(disciplines)
        if timeout_s:
            discs = [TimedDiscipline(d, timeout_s) for d in discs]
        super().__init__(discs)
        self.errors = errors or FirstErrors()

    @property
    def hung(self) -> list[str]:
        """The disciplines that timed out and are treated as hung for the rest of the run."""
        return sorted(d.name for d in self.disciplines.values() if getattr(d, "_hung", ""))

    def evaluate(self, calls, **kw):  # kw: partials=... as InProcessEvaluator.evaluate takes it
        results = super().evaluate(calls, **kw)
        for (name, _), res in zip(calls, results):
            if res.error:
                self.errors.note(name, res.error)
        return results
