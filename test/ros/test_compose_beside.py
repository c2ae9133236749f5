"""Discipline nodes composed into the coordinator's own process (``--compose coordinator``,
composed.Beside): the in-process optimum bit for bit, results handed to the coordinator by direct
call while no reader outside the process listens, published (and recorded) as soon as one does, and
a recorded run that history, report and resume read like any other."""
from __future__ import annotations

import copy
import json
import os
import subprocess
import time

import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.ros import coordinator_node
from bev_mdo.testing import PYTHON, REPO, ros_env

ROS_DOMAIN = 74
BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    from bev_mdo.ros.auth import new_key_file

    d = tmp_path_factory.mktemp("cfg")
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0, "signing": True,
                  "sign_key_file": new_key_file(d)}  # handed results are verified like received ones
    path = d / "c.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def _count_publishes(nodes) -> dict:
    """Wrap every result publisher of `nodes`; returns the live counts {discipline: DDS writes}."""
    counts = {n.discipline_name: 0 for n in nodes}
    for n in nodes:
        for pub in (n._mda_pub, n._result_pub):
            real = pub.publish

            def publish(msg, real=real, name=n.discipline_name):
                counts[name] += 1
                return real(msg)

            pub.publish = publish
    return counts


def _reference(config):
    return run_optimization(copy.deepcopy(config), InProcessEvaluator(resolve_disciplines(config)))


def test_beside_the_coordinator_gives_the_in_process_optimum_without_dds_writes(rclpy_context, config_path,
                                                                                monkeypatch):
    from bev_mdo.ros import evaluator as ros_evaluator
    from bev_mdo.ros.composed import Beside

    config = load_config(config_path)
    run_id = f"beside{os.getpid()}"
    beside = Beside(config, BUILTINS, rclpy_context, run_id=run_id)
    sent = []
    encode = ros_evaluator.wire.encode_request
    monkeypatch.setattr(ros_evaluator.wire, "encode_request", lambda m: sent.append(m) or encode(m))
    try:
        writes = _count_publishes(beside.nodes)
        res, stats = coordinator_node.run(config, context=rclpy_context, run_id=run_id, beside=beside)
        ref = _reference(config)
        assert res.objective == ref.objective and res.design == ref.design
        assert stats["data_flow_mdas"] > 0 and stats["retried"] == 0 and not stats["dropped"], stats
        # every node evaluated (its counters), none wrote a result to DDS: nobody outside listened
        assert all(n.counts["answered"] > 0 for n in beside.nodes), {n.discipline_name: dict(n.counts)
                                                                      for n in beside.nodes}
        assert writes == dict.fromkeys(BUILTINS, 0), writes
        assert sent == []  # nor did the coordinator write a request: the nodes took each by direct call
        assert beside._evaluator is None  # detached when the run ended
    finally:
        beside.close()


def _spy_codec(monkeypatch) -> dict:
    """Count every CDR encode/decode and every HMAC sign/verify of requests and results."""
    from bev_mdo.ros import auth, discipline_node, evaluator as ros_evaluator, wire

    calls = {k: 0 for k in ("encode_request", "encode_result", "decode_request", "decode_result",
                            "sign_request", "sign_result", "verify_request", "verify_result")}

    def spy(owner, name, attr=None):
        real = getattr(owner, attr or name)

        def counted(*a, **k):
            calls[name] += 1
            return real(*a, **k)

        monkeypatch.setattr(owner, attr or name, counted)

    assert ros_evaluator.wire is wire and discipline_node.wire is wire
    for name in ("encode_request", "encode_result", "decode_request", "decode_result"):
        spy(wire, name)
    for name in ("sign_request", "sign_result", "verify_request", "verify_result"):
        spy(auth.Signer, name)
    return calls


def test_direct_calls_skip_the_codec_and_signing_and_match_in_process_bit_for_bit(rclpy_context, config_path,
                                                                                monkeypatch):
    """With nobody outside the process listening, a data-flow MDA and a wave of hub-and-spoke
    requests go to the nodes and back without one CDR encode or decode and without one HMAC
    (signing is on in this config), and every output, point flag and point error is the
    in-process evaluator's bit for bit, failed points included."""
    import numpy as np

    from bev_mdo.ros.composed import Beside
    from bev_mdo.ros.coordinator_node import CoordinatorNode

    config = load_config(config_path)
    run_id = f"besidebits{os.getpid()}"
    beside = Beside(config, BUILTINS, rclpy_context, run_id=run_id)
    node = CoordinatorNode(config, run_id=run_id, context=rclpy_context, node_name="beside_bits_coordinator")
    assert node.evaluator.signer is not None
    beside.attach(node.evaluator)
    try:
        ev = node.evaluator
        ev.wait_for_disciplines(BUILTINS, 60.0)
        ev.warm_up(BUILTINS)
        ref = InProcessEvaluator(resolve_disciplines(config))
        rng = np.random.default_rng(7)
        n = 9
        request = {"motor_kw": rng.uniform(40, 160, n), "battery_kwh": rng.uniform(20, 90, n),
                   "gear_ratio": rng.uniform(5, 12, n)}
        request["motor_kw"][3] = np.nan  # a point that fails, named, in both
        request["battery_kwh"][5] = -1.0
        order = ["vehicle_mass", "motor_speed", "cost", "energy", "acceleration", "range"]
        calls = _spy_codec(monkeypatch)
        got = ev.evaluate_flow(order, request, n)
        assert got is not None and ev.flows >= 1
        want = ref.evaluate_flow(order, request, n)
        wave = [(d, {k: request[k] for k in ev.specs[d].inputs}) for d in ("vehicle_mass", "cost", "motor_speed")]
        got_wave = ev.evaluate(wave)
        want_wave = ref.evaluate(wave)
        assert calls == dict.fromkeys(calls, 0), calls  # nothing encoded, decoded, signed or verified
        assert not ev.dropped, dict(ev.dropped)
        for g, w in [*((got[d], want[d]) for d in order), *zip(got_wave, want_wave)]:
            assert sorted(g.outputs) == sorted(w.outputs)
            for k in w.outputs:
                assert np.array_equal(g.outputs[k], w.outputs[k], equal_nan=True), k
                assert g.outputs[k].tobytes() == np.asarray(w.outputs[k], dtype=float).tobytes(), k
            assert np.array_equal(g.ok, w.ok)
            assert sorted(g.point_errors) == sorted(w.point_errors)
        assert not got["vehicle_mass"].ok[3] and not got["range"].ok[5]  # the bad points failed in both
    finally:
        beside.close()
        node.evaluator.close()
        node.destroy_node()


def test_an_outside_reader_gets_signed_messages_and_the_same_answer(ros_domain, rclpy_context, config_path,
                                                                    monkeypatch):
    """A reader in another participant on the data-flow request topic and on one result topic (as
    a recorder is): those messages are then published, signed with the run's key (they verify),
    the composed nodes take the request from DDS and verify it as any node does, and the answer is
    the one the direct calls give."""
    import numpy as np
    from rclpy.executors import SingleThreadedExecutor

    from bev_mdo.ros import wire
    from bev_mdo.ros.auth import Signer, read_key
    from bev_mdo.ros.common import MDA_REQUEST_TOPIC, REQUEST_QOS, RESULT_QOS, mda_result_topic
    from bev_mdo.ros.composed import Beside
    from bev_mdo.ros.coordinator_node import CoordinatorNode
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult

    config = load_config(config_path)
    run_id = f"besidesigned{os.getpid()}"
    beside = Beside(config, BUILTINS, rclpy_context, run_id=run_id)
    node = CoordinatorNode(config, run_id=run_id, context=rclpy_context, node_name="beside_signed_coordinator")
    beside.attach(node.evaluator)
    other = rclpy.context.Context()
    rclpy.init(context=other, domain_id=ros_domain)
    probe = rclpy.create_node("beside_signed_reader", context=other)
    requests, results = [], []
    order = ["vehicle_mass", "motor_speed", "cost", "energy", "acceleration", "range"]
    request = {"motor_kw": np.array([80.0, 110.0]), "battery_kwh": np.array([40.0, 62.0]),
               "gear_ratio": np.array([8.2, 9.0])}
    try:
        ev = node.evaluator
        ev.wait_for_disciplines(BUILTINS, 60.0)
        ev.warm_up(BUILTINS)
        direct = ev.evaluate_flow(order, request, 2)
        subs = [probe.create_subscription(EvaluationRequest, MDA_REQUEST_TOPIC, requests.append, REQUEST_QOS,
                                          raw=True),
                probe.create_subscription(EvaluationResult, mda_result_topic("energy"), results.append, RESULT_QOS,
                                          raw=True)]
        energy = next(n for n in beside.nodes if n.discipline_name == "energy")
        roots = [n for n in beside.nodes if n._mda_sub is not None]
        deadline = time.monotonic() + 30.0
        while (ev._flow_pub.get_subscription_count() < len(roots) + 1
               or energy._mda_pub.get_subscription_count() < len(energy.local_consumers) + 2):
            assert time.monotonic() < deadline, "the outside reader never matched"
            time.sleep(0.02)
        calls = _spy_codec(monkeypatch)
        published = ev.evaluate_flow(order, request, 2)
        assert not ev.dropped and ev.retried == 0, (dict(ev.dropped), ev.retried)
        for d in order:
            for k in direct[d].outputs:
                assert published[d].outputs[k].tobytes() == direct[d].outputs[k].tobytes(), (d, k)
            assert np.array_equal(published[d].ok, direct[d].ok)
        ex = SingleThreadedExecutor(context=other)
        ex.add_node(probe)
        deadline = time.monotonic() + 10.0
        while (not requests or not results) and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        ex.shutdown()
        seen = dict(calls)  # before this test's own checks below (they go through the same Signer methods)
        signer = Signer(read_key(config["ros"]["sign_key_file"]))
        req = wire.decode_request(requests[-1])
        res = wire.decode_result(results[-1])
        assert req.run_id == run_id and res.run_id == run_id and res.discipline == "energy"
        assert len(req.signature) == 64 and signer.verify_request(req) is None
        assert len(res.signature) == 64 and signer.verify_result(res) is None
        # the request was signed once and verified by every root node that took it from DDS; energy's
        # result was signed and verified by the coordinator; the results nobody else reads were not
        assert seen["sign_request"] == 1 and seen["verify_request"] == len(roots), seen
        assert seen["sign_result"] == 1 and seen["verify_result"] == 1, seen
        for s in subs:
            probe.destroy_subscription(s)
    finally:
        probe.destroy_node()
        rclpy.shutdown(context=other)
        beside.close()
        node.evaluator.close()
        node.destroy_node()


def test_beside_publishes_while_an_outside_reader_listens(ros_domain, rclpy_context, config_path):
    """A reader in another participant (a recorder would be one) on the results: each result is then
    published, that reader gets it, and the coordinator takes it from DDS (nothing dropped twice)."""
    from bev_mdo.ros.common import RESULT_QOS, mda_result_topic
    from bev_mdo.ros.composed import Beside
    from bev_mdo_msgs.msg import EvaluationResult

    config = load_config(config_path)
    run_id = f"besideout{os.getpid()}"
    beside = Beside(config, BUILTINS, rclpy_context, run_id=run_id)
    other = rclpy.context.Context()
    rclpy.init(context=other, domain_id=ros_domain)
    probe = rclpy.create_node("beside_outside_reader", context=other)
    got = []
    try:
        writes = _count_publishes(beside.nodes)
        sub = probe.create_subscription(EvaluationResult, mda_result_topic("energy"), got.append, RESULT_QOS, raw=True)
        energy = next(n for n in beside.nodes if n.discipline_name == "energy")
        deadline = time.monotonic() + 30.0
        while energy._mda_pub.get_subscription_count() < len(energy.local_consumers) + 1:  # range's + the probe's
            assert time.monotonic() < deadline, "the outside reader never matched"
            time.sleep(0.02)
        from rclpy.executors import SingleThreadedExecutor

        res, stats = coordinator_node.run(config, context=rclpy_context, run_id=run_id, beside=beside)
        ref = _reference(config)
        assert res.objective == ref.objective and res.design == ref.design
        assert stats["retried"] == 0 and not stats["dropped"], stats
        assert writes["energy"] > 0  # published: someone outside listens
        assert writes["cost"] == 0    # nobody outside reads cost's results: handed over directly
        assert energy.counts["answered"] > 0
        ex = SingleThreadedExecutor(context=other)
        ex.add_node(probe)
        deadline = time.monotonic() + 10.0
        while len(got) < writes["energy"] and time.monotonic() < deadline:
            ex.spin_once(timeout_sec=0.05)
        assert len(got) == writes["energy"]
        ex.shutdown()
        probe.destroy_subscription(sub)
    finally:
        probe.destroy_node()
        rclpy.shutdown(context=other)
        beside.close()


def _cli(*argv, domain, cwd, timeout=300):
    out = subprocess.run([PYTHON, "-m", "bev_mdo", *map(str, argv)], env=ros_env(domain), cwd=cwd,
                         capture_output=True, text=True, timeout=timeout)
    assert out.returncode == 0, (argv, out.stderr[-3000:])
    return out


def test_recorded_run_composed_into_the_coordinator_reads_back_and_resumes(ros_domain, config_path, tmp_path):
    """``optimize --compose coordinator`` with the recorder: no discipline process, the in-process
    optimum, every data-flow request of the bag with each discipline's result; history, report and
    resume work on that bag."""
    from bev_mdo.bag.reader import open_bag

    raw = yaml.safe_load(config_path.read_text())
    raw["ros"] = {**raw["ros"], "domain_id": ros_domain}
    raw["ros"].pop("sign_key_file")  # the CLI signs with a per-run key of its own
    cfg = tmp_path / "leaf.yaml"
    cfg.write_text(yaml.safe_dump(raw, sort_keys=False))
    bag = tmp_path / "run"
    out = _cli("optimize", cfg, "--compose", "coordinator", "--json", "--quiet", "--bag", bag,
               domain=ros_domain, cwd=tmp_path)
    result = json.loads(out.stdout)
    ref = _reference(load_config(cfg))
    assert result["objective"] == ref.objective and result["design"] == ref.design
    assert result["dropped_messages"] == {} and result["retried_requests"] == 0, result
    # the run's nodes lived in the coordinator's process: only the recorder had a log of its own
    assert sorted(p.name for p in (bag / "logs").glob("*.log")) == ["recorder.log"]
    b = open_bag(bag)
    requests, results = {}, set()
    for msg, obj in b.decoded([t for t in b.topics if t.endswith("request") or t.endswith("result")]):
        if obj.run_id != result["run_id"] or int(getattr(obj, "inputs", getattr(obj, "outputs", None)).batch_size) == 0:
            continue
        if msg.topic.endswith("request"):
            requests[int(obj.evaluation_id)] = list(obj.flow) or [obj.discipline]
        else:
            results.add((int(obj.evaluation_id), obj.discipline))
    assert requests and any(len(ds) == len(BUILTINS) for ds in requests.values())  # data-flow MDAs recorded
    missing = [(e, d) for e, ds in requests.items() for d in ds if (e, d) not in results]
    assert not missing, f"requests recorded without their results: {missing[:5]}"
    hist = _cli("history", bag, "--csv", "-", domain=ros_domain, cwd=tmp_path).stdout.strip().splitlines()
    assert len(hist) >= 2 and "objective" in hist[0]
    _cli("report", bag, "--output-dir", tmp_path / "report", domain=ros_domain, cwd=tmp_path)
    assert list((tmp_path / "report").glob("*.md"))
    resumed = json.loads(_cli("resume", bag, "--json", "--quiet", "--no-record", domain=ros_domain,
                              cwd=tmp_path).stdout)
    assert resumed["objective"] == pytest.approx(ref.objective, rel=1e-6)


def test_ros2_run_coordinator_node_with_compose_coordinator(ros_domain, config_path, tmp_path):
    """``ros2 run bev_mdo coordinator_node --ros-args -p compose:=coordinator``: a whole run in one
    process, the in-process optimum; a compose value it cannot serve exits 2 with one line."""
    argv = [PYTHON, "-m", "bev_mdo.ros.run", "coordinator_node", "--ros-args", "-p", f"config:={config_path}"]
    out = subprocess.run(argv + ["-p", "compose:=coordinator"], env=ros_env(ros_domain), cwd=tmp_path,
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout[out.stdout.index("{"):])
    ref = _reference(load_config(config_path))
    assert got["result"]["objective"] == ref.objective and got["result"]["design"] == ref.design
    assert got["data_flow_mdas"] > 0 and got["retried"] == 0
    bad = subprocess.run(argv + ["-p", "compose:=all"], env=ros_env(ros_domain), cwd=tmp_path,
                         capture_output=True, text=True, timeout=120)
    assert bad.returncode == 2 and "compose must be coordinator" in bad.stderr and "Traceback" not in bad.stderr
