"""Fuzz: >= 10 000 malformed or foreign messages at the nodes during optimisations.

A separate fuzzer process (this file run as a script) waits until a coordinator is up,
then publishes in rounds at every discipline's request topic (wrong array lengths,
huge batch sizes and huge arrays, unknown and missing names, garbage names, run ids
and discipline names, NaN/Inf values, stale evaluation ids and other run ids) and at
the result topic. It paces itself on the nodes' own counters (/bev_mdo/node_stats), so
no message is lost to queue overflow, and reports what it sent. Meanwhile the test
runs optimisations back to back until the fuzzer is done; every one must equal the
in-process optimum, no node may crash, and every malformed request must show in the
node's counter of its reason.
"""
from __future__ import annotations

import array
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np

MIN_MESSAGES = 10_000


# -- the fuzzer process --------------------------------------------------------------------
_TAGS: dict[str, str] = {}  # discipline -> the frame_id binding its node serves (filled by fuzz_main)


def _fuzz_messages(disc, rng):
    """Yield (expected node counter, EvaluationRequest) for one discipline, endlessly."""
    from bev_mdo import protocol
    from bev_mdo.ros.common import stamp
    from bev_mdo_msgs.msg import EvaluationRequest

    ins = list(disc.inputs)

    def req(run_id="fuzz-run", eid=None, discipline=disc.name):
        m = EvaluationRequest()
        stamp(m.header)
        m.run_id, m.discipline = run_id, discipline
        m.header.frame_id = _TAGS.get(disc.name, "")
        m.evaluation_id = int(eid if eid is not None else rng.integers(1, 2**63))
        return m

    def good_cols(n=2):
        return {k: rng.uniform(1.0, 100.0, n) for k in ins}

    kinds = []

    def kind(f):
        kinds.append(f)
        return f

    @kind
    def wrong_length():
        m = req()
        protocol.to_named_array(good_cols(3), m.inputs)
        m.inputs.batch_size = int(rng.choice([0, 2, 4, 7]))
        return "rejected.malformed", m

    @kind
    def huge_batch_size():
        m = req()
        m.inputs.names = ins
        m.inputs.batch_size = 2**32 - 1
        m.inputs.values = [1.0] * len(ins)
        return "rejected.malformed", m

    @kind
    def unknown_name():
        m = req()
        cols = good_cols()
        cols[f"bogus_{int(rng.integers(1000))}"] = np.ones(2)
        protocol.to_named_array(cols, m.inputs)
        return "rejected.unknown_inputs", m

    @kind
    def missing_name():
        m = req()
        cols = good_cols()
        cols.pop(ins[int(rng.integers(len(ins)))])
        protocol.to_named_array(cols, m.inputs)
        return "rejected.missing_inputs", m

    @kind
    def garbage_names():
        m = req()
        m.inputs.names = ["!" + "".join(chr(int(c)) for c in rng.integers(33, 0x2FF, 12)) for _ in ins]
        m.inputs.batch_size = 1
        m.inputs.values = [0.0] * len(ins)
        return "rejected.malformed", m

    @kind
    def duplicate_names():
        m = req()
        m.inputs.names = [ins[0], ins[0]]
        m.inputs.batch_size = 1
        m.inputs.values = [1.0, 1.0]
        return "rejected.malformed", m

    @kind
    def garbage_run_id():
        m = req(run_id=rng.choice(["", "x" * 500, "bad\x07id", "\n\t"]))
        protocol.to_named_array(good_cols(), m.inputs)
        return "rejected.bad_run_id", m

    @kind
    def wrong_discipline():
        m = req(discipline=rng.choice(["", "nope", "\u2603" * 50, "energy" if disc.name != "energy" else "cost"]))
        protocol.to_named_array(good_cols(), m.inputs)
        return "rejected.wrong_discipline", m

    @kind
    def non_finite():  # well formed: evaluated, those points fail (as in-process)
        m = req(run_id=f"fuzz-other-{int(rng.integers(1000))}")
        cols = good_cols()
        cols[ins[0]][int(rng.integers(2))] = rng.choice([np.nan, np.inf, -np.inf])
        protocol.to_named_array(cols, m.inputs)
        return "non_finite", m

    @kind
    def stale_or_other_run():  # well formed: answered, and dropped by every coordinator
        m = req(run_id=f"fuzz-other-{int(rng.integers(1000))}", eid=int(rng.integers(1, 50)))
        protocol.to_named_array(good_cols(1), m.inputs)
        return "answered", m

    weights = np.array([3, 2, 2, 2, 2, 1, 1, 1, 1, 1], float)
    weights /= weights.sum()
    while True:
        yield kinds[int(rng.choice(len(kinds), p=weights))]()


def _huge(disc):
    """A request whose values array really is huge (> MAX_BATCH points)."""
    from bev_mdo import protocol
    from bev_mdo.ros.common import stamp
    from bev_mdo_msgs.msg import EvaluationRequest

    m = EvaluationRequest()
    stamp(m.header)
    m.run_id, m.discipline, m.evaluation_id = "fuzz-huge", disc.name, 1
    m.header.frame_id = _TAGS.get(disc.name, "")
    n = protocol.MAX_BATCH + 1
    m.inputs.names = [disc.inputs[0]]
    m.inputs.batch_size = n
    m.inputs.values = array.array("d", np.ones(n).tobytes())
    return "rejected.malformed", m


def _bogus_results(rng, n):
    from bev_mdo.ros.common import stamp
    from bev_mdo_msgs.msg import EvaluationResult

    for i in range(n):
        r = EvaluationResult()
        stamp(r.header)
        r.run_id = rng.choice([f"fuzz-other-{i}", "", "\u2603" * 300])
        r.evaluation_id = int(rng.integers(1, 2**63))
        r.discipline = rng.choice(["energy", "garbage\u2603"])
        r.point_ok = [True, False, True]
        r.outputs.names = ["energy_wh_per_km"]
        r.outputs.batch_size = 7
        r.outputs.values = [np.nan, np.inf]
        yield r


def fuzz_main(config_path: str, total: int, per_round: int, seed: int) -> int:
    import rclpy
    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.ros.common import ITERATION_TOPIC, REQUEST_QOS, RESULT_QOS, RESULT_TOPIC, request_topic
    from bev_mdo.ros.status import NodeStatsListener
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult

    rng = np.random.default_rng(seed)
    from bev_mdo.binding import tag_for

    config = load_config(config_path)
    discs = resolve_disciplines(config)
    _TAGS.update({d.name: tag_for(config, [d.name]) for d in discs})
    rclpy.init()
    node = rclpy.create_node("fuzzer")
    stats = NodeStatsListener(node)
    pubs = {d.name: node.create_publisher(EvaluationRequest, request_topic(d.name), REQUEST_QOS) for d in discs}
    res_pub = node.create_publisher(EvaluationResult, RESULT_TOPIC, RESULT_QOS)
    gens = {d.name: _fuzz_messages(d, rng) for d in discs}
    names = [d.name for d in discs]

    def ready(s):
        return (all(pubs[n].get_subscription_count() >= 1 and s.seen(n) for n in names)
                and node.count_publishers(ITERATION_TOPIC) >= 1)  # a coordinator is running
    if not stats.wait(ready, 60):
        print(json.dumps({"error": "discovery", "seen": list(stats.latest)}))
        return 3
    base = {n: stats.counts(n) for n in names}
    sent = {n: Counter() for n in names}
    n_sent = 0
    for i, d in enumerate(discs[:3]):  # a few truly huge arrays (8 MB each)
        key, msg = _huge(d)
        pubs[d.name].publish(msg)
        sent[d.name][key] += 1
        n_sent += 1
    results_sent = 0
    while n_sent < total:
        for n in names:
            for _ in range(per_round):
                key, msg = next(gens[n])
                pubs[n].publish(msg)
                sent[n][key] += 1
                n_sent += 1
        for r in _bogus_results(rng, 10):
            res_pub.publish(r)
            results_sent += 1

        # pace: wait until every node has taken all of it (received counts only grow)
        def caught_up(s):
            return all(s.counts(n)["received"] - base[n]["received"] >= sum(sent[n].values()) for n in names)
        if not stats.wait(caught_up, 60):
            break

    def accounted(s):
        return all(s.counts(n)[k] - base[n][k] >= v for n in names for k, v in sent[n].items())
    stats.wait(accounted, 60)
    final = {n: stats.counts(n) for n in names}
    out = {"sent": {n: dict(c) for n, c in sent.items()}, "total": n_sent, "results_sent": results_sent,
           "delta": {n: {k: final[n][k] - base[n][k] for k in set(final[n]) | set(base[n])} for n in names}}
    print(json.dumps(out))
    stats.close()
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(fuzz_main(sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])))


# -- the test --------------------------------------------------------------------------------
import pytest  # noqa: E402


BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


# This module's own ROS domain, in the 80-89 block of the fault tests (see test/conftest.py).
ROS_DOMAIN = 83


@pytest.fixture(scope="module")
def setup(ros_domain, tmp_path_factory):
    import yaml

    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.testing import REPO, ros_env

    d = tmp_path_factory.mktemp("fuzz")
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"timeout_s": 2.0, "retries": 10, "discovery_wait_s": 60.0}
    path = d / "fuzz.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    la = Launcher(ros_env(ros_domain), log_dir=d / "logs")
    try:
        for name in BUILTINS:
            la.add(name, discipline_argv(name, str(path)))
        la.supervise()
        yield {"config": str(path), "launcher": la, "logs": d / "logs", "env": ros_env(ros_domain)}
    finally:
        la.stop()


def test_ten_thousand_malformed_messages_change_nothing(rclpy_context, setup):
    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.mdo.driver import run_optimization
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.ros import coordinator_node

    config = load_config(setup["config"])
    ref = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    fuzzer = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), setup["config"], str(MIN_MESSAGES),
                               "100", "8"], env=setup["env"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    runs, dropped = 0, Counter()
    try:
        while True:  # optimisations back to back while the fuzzer is at work
            res, stats = coordinator_node.run(config, context=rclpy_context)
            runs += 1
            dropped.update(stats["dropped"])
            for k, v in ref.design.items():
                assert res.design[k] == pytest.approx(v, rel=1e-12), (runs, k)
            assert res.objective == pytest.approx(ref.objective, rel=1e-12)
            if fuzzer.poll() is not None:
                break
        out, err = fuzzer.communicate(timeout=120)
    finally:
        if fuzzer.poll() is None:
            fuzzer.kill()
            fuzzer.wait()
    assert fuzzer.returncode == 0, err[-3000:] + out[-1000:]
    report = json.loads(out.strip().splitlines()[-1])
    print(f"fuzz: {report['total']} requests + {report['results_sent']} results during {runs} optimisations; "
          f"coordinators dropped {dict(dropped)}")
    assert report["total"] >= MIN_MESSAGES
    for name, sent in report["sent"].items():
        delta = report["delta"][name]
        for key, n in sent.items():
            if key.startswith("rejected.") or key == "non_finite":
                # rejections only ever come from the fuzzer: the counts must match exactly
                assert delta.get(key, 0) == n, (name, key, delta)
        assert delta.get("rejected", 0) == sum(n for k, n in sent.items() if k.startswith("rejected."))
        assert delta.get("answered", 0) >= sent.get("answered", 0) + sent.get("non_finite", 0)
    # the foreign answers and the bogus results reached the coordinators and were dropped there
    assert dropped["other_run"] > 0
    assert all(n.restarts == 0 for n in setup["launcher"].nodes), [(n.label, n.restarts) for n in
                                                                   setup["launcher"].nodes]
    # rate-limited logs: far fewer warning lines than rejections
    for log in setup["logs"].glob("*.log"):
        rejected = report["delta"][log.stem].get("rejected", 0)
        lines = sum(1 for line in log.read_text(errors="replace").splitlines() if "rejected request" in line)
        assert lines <= max(20, rejected // 20), (log.stem, lines, rejected)
