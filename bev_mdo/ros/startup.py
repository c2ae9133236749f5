"""Start-up of a run's ROS evaluator: the waits before the first real request.

``wait_for_disciplines`` waits until every discipline of the run declared itself (DisciplineInfo,
accepted by ``RosEvaluator._on_info``) and every topic the run uses matched, then proves by a
handshake that every path delivers; ``wait_for_instances`` waits for a pool's instances;
``warm_up`` sends MDAs of no point before any timing. Each wait lasts as long as discovery makes
progress (fastwait.until) and raises DisciplineMissing, naming what is absent, once nothing changed
for the wait. A mixin of RosEvaluator (evaluator.py), which holds the node, topics and ledger.
"""
from __future__ import annotations

import functools
import sys
import time
from typing import Sequence

import numpy as np

from bev_mdo import binding
from bev_mdo.mdo import retry
from bev_mdo.ros.common import MDA_REQUEST_TOPIC, RESULT_TOPIC, endpoints, mda_result_topic, node_of, request_topic
from bev_mdo.ros.fastwait import STARTUP_CAP, until
from bev_mdo.stacks import StartupGaveUp
from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult


class DisciplineMissing(StartupGaveUp):
    """A needed discipline did not appear, match or answer within the discovery wait."""


class StartupWaits:
    """The start-up waits of RosEvaluator (a mixin: the evaluator's node, topics and ledger)."""

    def progress(self, names: Sequence[str] = ()) -> tuple:
        """What start-up progress is measured by (fastwait.until): the nodes on the graph, the
        declarations taken, the matches of our request and result topics and, with ``starting``
        (launcher.Launcher.progress), the CPU time of the run's processes not yet on the graph."""
        pubs = self._publishers
        return (self.starting() if self.starting is not None else (), tuple(sorted(self.node.get_node_names())), tuple(sorted(self.specs)), len(self.refused),
                sum(len(v) for v in self.instances.values()), self._result_sub.get_publisher_count(),
                tuple(p.get_subscription_count() for p in pubs.values()),
                tuple(s.get_publisher_count() for s in self._flow_subs.values()))

    def wait_for_disciplines(self, names: Sequence[str], wait_s: float, extra_subscribers: int = 0) -> None:
        """Block until every named discipline declared itself and matched our topics, then prove
        every path delivers (handshake). Waits as long as discovery makes progress (fastwait.until):
        raises DisciplineMissing naming the ones still absent once nothing changed for `wait_s`.
        `extra_subscribers`: readers of each request topic to wait for besides the discipline's (the
        run's recorder is waited for by name instead: coordinator_node.wait_for_recorder)."""
        for n in names:
            self._publisher(n)

        def missing() -> list[str]:
            out = []
            for n in names:
                ready = (
                    n in self.specs
                    and self._publishers[n].get_subscription_count() >= 1 + extra_subscribers
                    and self.node.count_publishers(RESULT_TOPIC) >= 1
                    and self._present(n, request_topic(n), subscriber=True)
                    # every reader in the graph matched: with other instances (another run's, a
                    # refused one, a recorder) on the topic, a count alone could be reached without ours;
                    # a reader of another type (a squatter) can never match, and is not waited for
                    and self._publishers[n].get_subscription_count() >= self._readers(request_topic(n))
                    and self._present(n, RESULT_TOPIC, subscriber=False)
                )
                if not ready:
                    out.append(n)
            return out

        spin = functools.partial(self._executor.spin_once, timeout_sec=0.05)
        progress = functools.partial(self.progress, names)
        if not until(lambda: not missing(), wait_s, spin, progress,
                     lambda: f"discipline(s) {missing()} ({len(self.specs)} of {len(names)} declared)"):
            gone = missing()
            if gone:
                refused = [f"{k}: {why}" for k, why in self.refused.items() if k.split(" ")[0] in gone]
                if refused:
                    raise DisciplineMissing(f"discipline(s) {gone}: no instance of this run's configuration "
                                            f"(nothing changed for {wait_s:g} s); refused " + " | ".join(refused))
                elsewhere = binding.bound_elsewhere(gone, self.other_runs, self.run_id)
                raise DisciplineMissing(
                    f"discipline(s) {gone} not found on ROS domain: discovery made no progress for {wait_s:g} s"
                    + (elsewhere or " (is each node running, with the same ROS_DOMAIN_ID and discovery settings? see "
                       "its log in the run's logs folder; the limits of one domain are in docs/scaling.md; "
                       "ros.discovery_wait_s sets this bound)"))
        # Our result subscription must be matched to every discipline's publisher too.
        if not until(lambda: self._result_sub.get_publisher_count() >= len(set(names)), wait_s, spin, progress,
                     "the result topic to match every discipline"):
            raise DisciplineMissing(f"result topic not matched for all of {list(names)}: no progress for {wait_s:g} s")
        # Declarations that arrived with ours (other instances on the domain) are judged now: once
        # the run evaluates, only the hot subscriptions are served.
        for _ in range(16):
            self._executor.spin_once(timeout_sec=0.0)
        flow_ok = self.flow_plan(names) is not None
        if not flow_ok:
            self.log.info("data flow not used (a node does not offer it, or the graph has a loop): "
                                        "MDAs run in waves")
        else:
            # Data flow: the disciplines without sources read the MDA request topic and we read every
            # node's results. (Node-to-node result topics are TRANSIENT_LOCAL: a late match loses nothing.)
            self._flow_topics(names)
            roots = {n for n, src in self.flow_plan(names).items() if not src}
            if not until(lambda: (self._flow_pub.get_subscription_count()
                                  >= max(len(roots), self._readers(MDA_REQUEST_TOPIC))
                                  and all(self._flow_subs[n].get_publisher_count() >= 1 for n in names)
                                  and all(self._present(n, MDA_REQUEST_TOPIC, subscriber=True) for n in roots)
                                  and all(self._present(n, mda_result_topic(n), subscriber=False) for n in names)),
                         wait_s, spin, progress, "the data-flow topics to match"):
                raise DisciplineMissing(f"data-flow topics not matched for all of {list(names)}: no progress "
                                        f"for {wait_s:g} s")
        self.handshake(names, wait_s, flow_ok)

    def handshake(self, names: Sequence[str], wait_s: float = 20.0, data_flow: bool | None = None) -> None:
        """Prove that every path a run uses delivers, before the first real request.

        The graph counts above are what THIS process sees: our reader knowing a node's result
        writer does not mean that writer knows our reader yet (each side matches the other on
        its own discovery traffic), and a VOLATILE result published before the writer matched us
        is lost, not late (seen on a loaded host as a first retry). So every discipline answers one request of no
        point (hub and spoke) and, when the MDA uses data flow, one empty data-flow MDA, re-sent
        with a fresh evaluation id every 0.1-1 s until answered: a round trip shows both ends of
        every topic matched. Nothing is evaluated or counted; a late answer to an earlier probe is
        ignored (``probe_late``). It waits as long as something progresses (a probe answered, the
        graph changed) and raises DisciplineMissing naming a discipline that did not answer once
        nothing changed for `wait_s`."""
        names = list(dict.fromkeys(names))
        if data_flow is None:
            data_flow = self.flow_plan(names) is not None and all(n in self._flow_subs for n in names)
        kept = len(self.accepted)
        start, last, state, shown = time.monotonic(), time.monotonic(), self.progress(names), time.monotonic()
        rounds = [("request", n) for n in names] + ([("flow", None)] if data_flow else [])
        for kind, name in rounds:
            interval = 0.1
            while True:
                eid = self.ledger.new_id(probe=True)
                if kind == "request":
                    req = self._request(eid, name, {k: np.zeros(0) for k in self.specs[name].inputs},
                                        self._tag([name]), iteration=0)
                    keys = [(eid, name)]
                    self._pending[keys[0]] = p = retry.Sent(0, name, req, 0, 0)
                else:
                    req = self._request(eid, "", {}, self._tag(names), flow=names, iteration=0)
                    keys = [(eid, n) for n in names]
                    for i, n in enumerate(names):
                        self._pending[(eid, n)] = retry.Sent(i, n, req, 0, 0, flow=True)
                    p = self._pending[keys[0]]  # one message for every discipline
                self._send(p)
                self._wait_pending(interval)
                late = [k[1] for k in keys if k in self._pending]
                for k in keys:
                    self._pending.pop(k, None)
                now = time.monotonic()
                if not late:
                    last = now  # an answer is progress
                    break
                if (s := self.progress(names)) != state:
                    state, last = s, now
                if now - last >= wait_s or now - start > STARTUP_CAP * wait_s:  # as fastwait.until
                    why = f"nothing changed for {wait_s:g} s" if now - last >= wait_s else f"{now - start:.0f} s in all"
                    hint = "; nodes with a ros.sign_key_file drop unsigned requests: give this run the same key"
                    raise DisciplineMissing(f"discipline(s) {late} are matched but did not answer a probe "
                                            f"({kind.replace('flow', 'data flow')}); {why}" + hint * (self.signer is None))
                if now - shown >= 2.0:
                    shown = now
                    print(f"[start-up] waiting for {late} to answer a probe; gives up in "
                          f"{wait_s - (now - last):.0f} s without progress", file=sys.stderr, flush=True)
                interval = min(2 * interval, 1.0)
        del self.accepted[kept:]
        self._results = {}

    def _wait_pending(self, seconds: float) -> None:
        """Take results until nothing is pending or `seconds` passed (no re-send)."""
        self._take_until(time.monotonic() + seconds)

    def _present(self, discipline: str, topic: str, subscriber: bool) -> bool:
        """True once an accepted instance of `discipline` is in the graph as a subscriber (publisher)
        of `topic`: a refused instance on the same topic does not make this run ready."""
        return bool(self._present_on(discipline, topic, subscriber)[0])

    def _readers(self, topic: str) -> int:
        """Readers of request topic `topic` in the graph that can match our writer (its type)."""
        return len(endpoints(self.node, topic, EvaluationRequest, warn=True))

    def _present_on(self, discipline: str, topic: str, subscriber: bool = True) -> tuple[set[str], int]:
        """(accepted instances of `discipline` subscribed to (publishing on) `topic`, all of them of its type:
        requests are read, results published)."""
        accepted = self.instances.get(discipline, set())
        infos = endpoints(self.node, topic, EvaluationRequest if subscriber else EvaluationResult, subscriber, True)
        present = set()
        for i in infos:
            full = node_of(i)
            if full in accepted:
                present.add(full)
            elif i.node_name in accepted:
                present.add(i.node_name)
        return present, len(infos)

    def warm_up(self, names: Sequence[str], rounds: int = 2) -> None:
        """Send `rounds` MDAs of no point through the matched graph, before any timing (call it
        after every start-up wait, the recorder's included, so a recording has all of it).

        The first samples between a new writer and its readers cost more than the later ones
        (measured: the first MDA of a run took 3.9-4.2 ms against 2.6-2.8 ms for the rest; after
        one empty MDA 3.2-3.7 ms, after two 2.8-2.9 ms). The first round is the handshake (every
        path, with short re-sends: nothing is lost to a late match); the others go the way the MDA
        goes: one data-flow MDA for a feed-forward graph, else one wave of empty requests (a loop
        is iterated hub and spoke; data flow cannot start a loop, so it is never tried there).
        An empty MDA evaluates nothing, so the evaluation counts do not change; its results are
        not kept in ``accepted`` or ``flows``. A recorder sees its requests and results."""
        kept, flows = len(self.accepted), self.flows
        names = list(names)
        self.handshake(names)
        for _ in range(rounds - 1):
            if self.evaluate_flow(names, {}, 0) is None:
                self.evaluate([(n, {k: np.zeros(0) for k in self.specs[n].inputs}) for n in names])
        del self.accepted[kept:]
        self.flows = flows

    def wait_for_instances(self, name: str, count: int, wait_s: float) -> list[str]:
        """Block until `count` accepted instances of `name` read its request topic and our writer
        matched them all (a pool ready to share); returns them. DisciplineMissing once nothing
        changed for `wait_s` (fastwait.until)."""
        self._publisher(name)

        def ready() -> bool:
            self._info_t = 0.0
            self._poll_info()
            present, readers = self._present_instances(name)
            return len(present) >= count and self._publisher(name).get_subscription_count() >= readers

        if not until(ready, wait_s, functools.partial(self._executor.spin_once, timeout_sec=0.05),
                     functools.partial(self.progress, [name]), f"{count} instances of {name!r}"):
            raise DisciplineMissing(f"{len(self._present_instances(name)[0])} of {count} instances of {name!r} "
                                    f"(nothing changed for {wait_s:g} s)" + (f"; refused {self.refused}" if self.refused else ""))
        return sorted(self._present_instances(name)[0])
