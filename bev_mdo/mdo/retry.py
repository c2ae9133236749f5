"""When to re-send, to whom, and when to give up: the timing decisions of a distributed
evaluation, independent of any transport (no ROS import; tested in milliseconds).

The orchestrator (orchestrator.py) sends, receives and waits through its transport; what it does
when an answer is late comes from here, as data it then carries out: ``Sent`` is the entry the
ledger (ledger.py) keeps per (evaluation id, discipline), ``Policy`` holds ``ros.timeout_s`` and
``ros.retries``, and ``resend_round`` (a whole wave), ``share_steps`` (a pool's shares) and
``flow_share_steps`` (the row shares of a pooled data-flow MDA) decide what a late or lost entry
becomes; ``Shares`` joins the answers of row shares in row order.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from bev_mdo.mdo.discipline import EvalResult, describe_row, join_errors
from bev_mdo.mdo.ledger import Key

LEFT = "left the ROS graph"  # why a share is re-sent when its instance is gone from the graph


@dataclass
class Sent:
    """One outstanding answer: (evaluation id, discipline) of a request sent at ``sent_ns``."""

    index: int           # the call's place in the wave (data flow: the discipline's place in the MDA)
    discipline: str
    request: Any         # the transport's request (its attempt number is set from ``tries``)
    n: int               # rows
    sent_ns: int         # monotonic clock, ns
    flow: bool = False   # part of a data-flow MDA (one request for all its disciplines)
    target: str = ""     # a pool's share: the instance it is addressed to
    start: int = -1      # a pool's share: its first row in the batch (-1: the whole batch)
    tries: int = 0       # attempts made before this one
    inputs: Any = None   # the request's columns ({name: (n,)}), to name its points


@dataclass(frozen=True)
class Policy:
    """How long an answer may take (``timeout_s``) and how often a request is re-sent (``retries``)."""

    timeout_s: float
    retries: int

    def late(self, sent: Sent, now_ns: int) -> bool:
        """True once `sent` has waited its whole timeout."""
        return now_ns >= sent.sent_ns + self.timeout_s * 1e9

    def due_s(self, pending: Iterable[Sent]) -> float:
        """The monotonic time (s) at which the first of `pending` is late."""
        return min(p.sent_ns * 1e-9 for p in pending) + self.timeout_s

    def exhausted(self, tries: int) -> bool:
        """No try is left after `tries` re-sends."""
        return tries >= self.retries

    def no_answer(self, discipline: str) -> str:
        """The error of points whose every attempt timed out."""
        return f"{discipline}: no answer after {self.retries + 1} attempts of {self.timeout_s:g} s"

    def waited(self) -> str:
        return f"no answer after {self.timeout_s:g} s"


def points(sent: Sent) -> str:
    """The points of `sent` for a message: `` (motor_kw=88, gear_ratio=8)``, or the first of several."""
    if not sent.inputs or sent.n < 1:
        return ""
    first = describe_row({k: np.asarray(v) for k, v in sent.inputs.items()}, 0)
    return f" ({first})" if sent.n == 1 else f" ({sent.n} points, the first {first})"


def resend_round(pending: Mapping[Key, Sent], attempt: int) -> list[tuple[Sent, list[str]]]:
    """A wave timed out: each still unanswered request once, with the disciplines it waits for
    (a data-flow request is one message for all of its disciplines). Sets ``tries`` to `attempt`."""
    out: dict[int, tuple[Sent, list[str]]] = {}
    for p in pending.values():
        out.setdefault(id(p.request), (p, []))[1].append(p.discipline)
        p.tries = attempt
    return list(out.values())


def hung(unanswered: Mapping[Key, Sent], sources_of: Callable[[Sent], Iterable[str]]) -> list[str]:
    """The disciplines that let every attempt time out, in order: each one's points fail and so
    do its later requests. A data-flow entry counts only if none of its sources (``sources_of``)
    is unanswered too (else it never had its inputs)."""
    out: dict[str, None] = {}
    for (eid, d), p in unanswered.items():
        if not p.flow or not any((eid, s) in unanswered for s in sources_of(p)):
            out.setdefault(d)
    return list(out)


@dataclass
class Step:
    """What to do with one late or lost entry of a pooled wave."""

    key: Key
    sent: Sent
    action: str      # "give_up" (its points fail), "resend" (whole batch, same request), "reshare"
    why: str         # for the log: LEFT or Policy.waited()
    blame: bool      # its instance is to be marked failed (it held a share)


def share_steps(policy: Policy, pending: Mapping[Key, Sent], now_ns: int,
                gone: set[tuple[str, str]]) -> list[Step]:
    """The entries of a pooled wave that are late, or whose instance left (``gone``: (discipline,
    instance) pairs), and what to do with each. A share given up or re-split is no longer
    outstanding (the caller closes or reassigns it in the ledger); a whole batch is re-sent as is."""
    steps = []
    for key, p in pending.items():
        lost = (p.discipline, p.target) in gone
        if not lost and not policy.late(p, now_ns):
            continue
        why = LEFT if lost else policy.waited()
        if policy.exhausted(p.tries):
            action = "give_up"
        elif p.start < 0:
            action = "resend"
        else:
            action = "reshare"
        steps.append(Step(key, p, action, why, bool(p.target)))
    return steps


@dataclass
class ShareStep:
    """What to do with a late or lost row share of a pooled data-flow MDA (all its entries)."""

    eid: int
    items: list[tuple[Key, Sent]]
    blame: set[tuple[str, str, int]]   # (discipline, instance, rows) to mark failed
    give_up: bool                      # its missing answers fail; else it is re-sent whole
    why: str


def flow_share_steps(policy: Policy, pending: Mapping[Key, Sent], now_ns: int, gone: set[tuple[str, str]],
                     plan: Mapping[str, Mapping[str, str]], tries_of: Callable[[int], int]) -> list[ShareStep]:
    """The row shares (by evaluation id) with an entry late or lost. To blame: an instance that
    left, or a waited-for one whose sources all answered (it had its inputs). ``tries_of(eid)``:
    the share's re-sends so far."""
    shares: dict[int, list[tuple[Key, Sent]]] = {}
    for key, p in pending.items():
        shares.setdefault(key[0], []).append((key, p))
    steps = []
    for eid, items in shares.items():
        late = any(policy.late(p, now_ns) for _, p in items)
        lost = [p for _, p in items if (p.discipline, p.target) in gone]
        if not late and not lost:
            continue
        waiting = {p.discipline for _, p in items}
        blame = {(p.discipline, p.target, p.n) for _, p in items if p.target and (
            (p.discipline, p.target) in gone or not set(plan[p.discipline].values()) & waiting)}
        steps.append(ShareStep(eid, items, blame, policy.exhausted(tries_of(eid)),
                               LEFT if lost else policy.waited()))
    return steps


def pick(live: Sequence[str], eid: int, tries: int) -> str:
    """The instance a re-sent share goes to: the live ones in turn, by share and try."""
    return live[(eid + tries) % len(live)]


def join_rows(parts: Iterable[tuple[int, EvalResult]], keys: Sequence[str] | None = None) -> EvalResult:
    """The results of row shares (first row, result) joined in row order into the result of the
    whole batch: outputs `keys` (default: the first share's), point errors renumbered, compute
    times summed, partials when every share has them."""
    parts = sorted(parts, key=lambda t: t[0])
    if keys is None:
        keys = tuple(parts[0][1].outputs)
    outs = {k: np.concatenate([np.asarray(r.outputs[k], dtype=float) for _, r in parts]) for k in keys}
    ok = np.concatenate([np.asarray(r.ok, dtype=bool) for _, r in parts])
    error, why = join_errors(parts)
    res = EvalResult(outs, ok, error, float(sum(r.compute_time_s for _, r in parts)), point_errors=why)
    if all("partials" in r.extra for _, r in parts):
        pk = parts[0][1].extra["partials"].keys()
        res.extra["partials"] = {k: np.concatenate([np.asarray(r.extra["partials"][k]) for _, r in parts])
                                 for k in pk if all(k in r.extra["partials"] for _, r in parts)}
    return res


@dataclass
class Shares:
    """The answers of row shares being collected: per call (a wave's index, or a data-flow MDA's
    discipline index) the (first row, result) of each answered share. A data-flow share (one
    evaluation id for all the MDA's disciplines) also keeps its rows and tries, and is dropped
    whole when re-sent."""

    got: dict[int, dict[int, tuple[int, EvalResult]]] = field(default_factory=dict)  # eid -> index -> part
    meta: dict[int, tuple[int, int, int]] = field(default_factory=dict)              # eid -> (first, stop, tries)

    def sent(self, eid: int, first: int, stop: int, tries: int) -> None:
        self.meta[eid] = (first, stop, tries)

    def add(self, eid: int, index: int, first: int, res: EvalResult) -> None:
        self.got.setdefault(eid, {})[index] = (first, res)

    def tries(self, eid: int) -> int:
        return self.meta[eid][2]

    def drop(self, eid: int) -> list[int]:
        """Forget share `eid` (it is re-sent under a new id); the indices that had answered."""
        self.meta.pop(eid, None)
        return list(self.got.pop(eid, {}))

    def join(self, index: int, keys: Sequence[str] | None = None) -> EvalResult:
        """Every answered share of call `index`, joined in row order."""
        return join_rows([got[index] for got in self.got.values() if index in got], keys)

    def indices(self) -> set[int]:
        return {i for got in self.got.values() for i in got}
