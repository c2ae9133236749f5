"""The request ledger of a distributed evaluation, independent of any transport (no ROS import).

A coordinator sends requests, each with an evaluation id (unique in its run) addressed to one
discipline (or, for a data-flow MDA, one id for all the disciplines of the MDA: one entry per
(id, discipline)), and accepts at most one answer per entry. ``binding_of(entry)`` is the binding
an answer must echo (the ROS evaluator: the request's frame_id, which names the fingerprints).
An answer ``match`` refuses is counted in ``dropped`` by reason: ``fingerprint`` (another
binding), ``late_share`` (a share given to another instance), ``duplicate`` (answered or given up
already), ``mismatched`` (an outstanding evaluation answered by another discipline) or ``stale``
(nothing of the kind outstanding); a late answer to a readiness probe only in ``probe_late``.

The orchestrator (orchestrator.py) keeps one per run; the run id check (``other_run``) and the
signature check come before ``match``, in the transport (ros/evaluator.py).
"""
from __future__ import annotations

from collections import Counter
from typing import Any, Callable, Generic, TypeVar

E = TypeVar("E")
Key = tuple[int, str]  # (evaluation id, discipline)


class Ledger(Generic[E]):
    """Outstanding, answered and reassigned requests of one run, and why answers were dropped."""

    def __init__(self, binding_of: Callable[[E], str] = lambda entry: "", first_id: int = 1):
        self.pending: dict[Key, E] = {}
        self._binding_of = binding_of
        self.answered: set[Key] = set()
        self.late: set[Key] = set()
        self.probes: set[int] = set()
        self.dropped: Counter[str] = Counter()
        self.probe_late = 0
        self._next = first_id

    def new_id(self, probe: bool = False) -> int:
        """The next evaluation id (a readiness probe's when ``probe``: its late answers are not drops)."""
        eid = self._next
        self._next += 1
        if probe:
            self.probes.add(eid)
        return eid

    @property
    def next_id(self) -> int:
        """The id ``new_id`` gives next."""
        return self._next

    def open(self, eid: int, discipline: str, entry: E) -> E:
        """Record ``entry`` as outstanding for (eid, discipline)."""
        self.pending[(eid, discipline)] = entry
        return entry

    def match(self, eid: int, discipline: str, binding: str) -> E | None:
        """The outstanding entry an answer (eid, discipline, echoed binding) belongs to, or None
        with the reason counted."""
        key = (eid, discipline)
        entry = self.pending.get(key)
        if entry is not None:
            if binding != self._binding_of(entry):
                self.dropped["fingerprint"] += 1  # answered for another configuration than this run's
                return None
            return entry
        if eid in self.probes:
            self.probe_late += 1
        elif key in self.late:
            self.dropped["late_share"] += 1
        elif key in self.answered:
            self.dropped["duplicate"] += 1
        elif any(k[0] == eid for k in self.pending):
            self.dropped["mismatched"] += 1
        else:
            self.dropped["stale"] += 1
        return None

    def settle(self, eid: int, discipline: str) -> E:
        """(eid, discipline) answered: no longer outstanding; another answer is a duplicate."""
        key = (eid, discipline)
        self.answered.add(key)
        return self.pending.pop(key)

    def close(self, key: Key) -> Any:
        """Given up without an answer (its points fail); a later answer is dropped as a duplicate."""
        self.answered.add(key)
        return self.pending.pop(key, None)

    def reassign(self, key: Key) -> Any:
        """Taken from its instance (to be re-sent under a new id); a later answer is a late share."""
        self.late.add(key)
        return self.pending.pop(key, None)

    def drop(self, reason: str) -> None:
        """Count an answer dropped by the transport before ``match`` (other run, signature, malformed)."""
        self.dropped[reason] += 1
