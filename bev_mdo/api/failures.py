"""Failures named where the user looks, for the in-process transport.

- ``FirstErrors``: the first error of each failing discipline, printed once to the console.
- ``NamingInProcessEvaluator``: the in-process evaluator reporting first errors (of the run's
  ``RunConfig.timed_disciplines``: each call bounded, mdo/timed.py).
"""
from __future__ import annotations

import sys

from bev_mdo.mdo.discipline import first_error_line
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


class NamingInProcessEvaluator(InProcessEvaluator):
    """In-process evaluator (of ``RunConfig.timed_disciplines``) with first errors named on the console."""

    def __init__(self, disciplines, errors: FirstErrors | None = None):
        super().__init__(disciplines)
        self.errors = errors or FirstErrors()

    def evaluate(self, calls, **kw):  # kw: partials=... as InProcessEvaluator.evaluate takes it
        results = super().evaluate(calls, **kw)
        for (name, _), res in zip(calls, results):
            if res.error:
                self.errors.note(name, res.error)
        return results
