"""Worker pools over ROS: several instances of one discipline share each batch.

One set of node processes serves the module: the built-ins, two energy instances and three
instances of a test discipline whose cost is a fixed wait per design (pool_discipline.py).
Every answer is compared bitwise with the in-process one.
"""
from __future__ import annotations

import copy
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines, run_settings  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.ros.status import NodeStatsListener  # noqa: E402
from bev_mdo.ros.evaluator import RosEvaluator  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402

ROS_DOMAIN = 71
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from pool_discipline import WaitPerDesign  # noqa: E402

BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
WAIT_S = 0.002
TIMEOUT_S = 2.0


def _raw(wait_s=WAIT_S, pool="share", pool_data_flow=True):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = BUILTINS + [{"name": "wait", "class": "pool_discipline:WaitPerDesign",
                                      "options": {"wait_s_per_design": wait_s}}]
    raw["ros"] = {"timeout_s": TIMEOUT_S, "retries": 3, "discovery_wait_s": 60.0, "signing": False, "pool": pool,
                 "pool_data_flow": pool_data_flow}
    return raw


@pytest.fixture(scope="module")
def paths(tmp_path_factory):
    d = tmp_path_factory.mktemp("cfg")
    out = {}
    for key, raw in (("base", _raw()), ("other", _raw(wait_s=0.003)), ("redundant", _raw(pool="redundant")),
                     ("waves", _raw(pool_data_flow=False))):
        out[key] = d / f"{key}.yaml"
        out[key].write_text(yaml.safe_dump(raw, sort_keys=False))
    return out


def _env(domain):
    env = ros_env(domain)
    env["PYTHONPATH"] = f"{HERE}:{REPO}:{env['PYTHONPATH']}"
    return env


@pytest.fixture(scope="module")
def launcher(ros_domain, paths, tmp_path_factory):
    launcher = Launcher(_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for name in BUILTINS:
        launcher.add(name, discipline_argv(name, str(paths["base"])))
    launcher.add("energy#1", discipline_argv("energy", str(paths["base"]), instance="e1"))
    for k in range(3):
        launcher.add(f"wait#{k}", discipline_argv("wait", str(paths["base"]), instance=f"w{k}"))
    yield launcher
    launcher.stop()


@pytest.fixture()
def evaluator(rclpy_context, launcher, paths):
    node = rclpy.create_node("pool_test_coordinator", context=rclpy_context)
    ev = RosEvaluator(node, config=load_config(paths["base"]), timeout_s=TIMEOUT_S, retries=3)
    yield ev
    ev.close()
    node.destroy_node()


def _batch(n, seed=0):
    rng = np.random.default_rng(seed)
    return {"motor_kw": rng.uniform(40, 120, n), "gear_ratio": rng.uniform(1, 11, n)}


def _reference(batch):
    return WaitPerDesign(0.0).compute(batch)["wait_value"]


def _points(ev, name="wait"):
    return {i: s.points for i, s in ev.pools[name].stats.items()}


def test_batch_is_split_among_instances_and_joined_in_order(evaluator):
    live = evaluator.wait_for_instances("wait", 3, 60.0)
    assert len(live) == 3
    batch = _batch(300)
    res = evaluator.evaluate([("wait", batch)])[0]
    assert res.ok.all(), res.error
    assert np.array_equal(res.outputs["wait_value"], _reference(batch))  # bitwise
    points = _points(evaluator)
    assert sorted(points) == live and all(p >= 1 for p in points.values()) and sum(points.values()) == 300
    shares = [a for a in evaluator.accepted if a[1] == "wait"]
    assert len(shares) == 3 and len({a[2] for a in shares}) == 3  # one share each, from three instances
    # a second batch is split by the measured throughput and still joins to the same answer
    batch = _batch(500, seed=1)
    res = evaluator.evaluate([("wait", batch), ("wait", _batch(7, seed=2))])
    assert np.array_equal(res[0].outputs["wait_value"], _reference(batch))
    assert np.array_equal(res[1].outputs["wait_value"], _reference(_batch(7, seed=2)))
    assert sum(_points(evaluator).values()) == 807
    summary = evaluator.pool_summary()["wait"]
    assert all(s["throughput_points_per_s"] > 0 and s["failures"] == 0 for s in summary.values())


def test_failed_points_of_shares_are_named_by_their_index_in_the_batch(evaluator):
    """Each instance numbers the rows of its own share; the joined result names the batch's points."""
    evaluator.wait_for_instances("wait", 3, 60.0)
    batch = _batch(300, seed=3)
    bad = [5, 150, 299]
    batch["gear_ratio"][bad] = np.nan
    res = evaluator.evaluate([("wait", batch)])[0]
    assert len({a[2] for a in evaluator.accepted if a[1] == "wait"}) > 1  # the batch was split
    assert np.flatnonzero(~res.ok).tolist() == bad
    assert sorted(res.point_errors) == bad
    for i in bad:
        assert res.point_errors[i].reason == "wait: non-finite input"
        assert f"wait: non-finite input at point {i} (" in res.error


def test_shares_go_only_to_their_instance(rclpy_context, evaluator):
    evaluator.wait_for_instances("wait", 3, 60.0)
    listener = NodeStatsListener(rclpy.create_node("pool_stats", context=rclpy_context))
    try:
        evaluator.evaluate([("wait", _batch(90))])
        # each instance ignored the two shares addressed to the others, and answered its own
        assert listener.wait(lambda l: l.counts("wait")["ignored.other_instance"] >= 6
                             and l.counts("wait")["points"] >= 90, 10.0), listener.latest
        assert evaluator.dropped["duplicate"] == 0
    finally:
        listener.close()


def test_redundant_mode_sends_every_batch_to_every_instance(rclpy_context, launcher, paths):
    node = rclpy.create_node("pool_redundant", context=rclpy_context)
    ev = RosEvaluator(node, config=load_config(paths["redundant"]), timeout_s=TIMEOUT_S, retries=3)
    listener = NodeStatsListener(rclpy.create_node("pool_stats_r", context=rclpy_context))
    try:
        ev.wait_for_instances("wait", 3, 60.0)
        before = {i: d["counts"].get("answered", 0) for i, d in listener.latest.items()}
        batch = _batch(20)
        res = ev.evaluate([("wait", batch)])[0]
        assert np.array_equal(res.outputs["wait_value"], _reference(batch))
        assert [a[1] for a in ev.accepted] == ["wait"] and not ev.pool_summary()
        waits = lambda l: [i for i, d in l.latest.items() if d["discipline"] == "wait"  # noqa: E731
                           and d["counts"].get("answered", 0) > before.get(i, 0)]
        assert listener.wait(lambda l: len(waits(l)) == 3, 10.0)  # all three answered the whole batch
    finally:
        listener.close()
        ev.close()
        node.destroy_node()


def test_instance_with_other_configuration_is_refused_with_the_difference(evaluator, launcher, paths):
    launcher.add("wait#other", discipline_argv("wait", str(paths["other"]), instance="wx"))
    try:
        evaluator.wait_for_instances("wait", 3, 60.0)
        deadline = 200
        while not any(k.startswith("wait ") for k in evaluator.refused) and deadline:
            evaluator._executor.spin_once(timeout_sec=0.1)
            deadline -= 1
        why = [w for k, w in evaluator.refused.items() if k.startswith("wait ")]
        assert why and "options.wait_s_per_design: 0.003 (this run: 0.002)" in why[0], evaluator.refused
        batch = _batch(64)
        res = evaluator.evaluate([("wait", batch)])[0]
        assert np.array_equal(res.outputs["wait_value"], _reference(batch))
        assert not any("wx" in i for i in _points(evaluator))  # it got no share
    finally:
        launcher.remove("wait#other")


def test_joining_instance_gets_work_from_the_next_batch(evaluator, launcher, paths):
    evaluator.wait_for_instances("wait", 3, 60.0)
    evaluator.evaluate([("wait", _batch(60))])
    launcher.add("wait#3", discipline_argv("wait", str(paths["base"]), instance="w3"))
    try:
        live = evaluator.wait_for_instances("wait", 4, 60.0)
        batch = _batch(120, seed=3)
        before = _points(evaluator)
        res = evaluator.evaluate([("wait", batch)])[0]
        assert np.array_equal(res.outputs["wait_value"], _reference(batch))
        new = [i for i in live if "w3" in i]
        assert new and _points(evaluator)[new[0]] - before.get(new[0], 0) >= 1
    finally:
        launcher.remove("wait#3")


def test_a_stalled_instance_has_its_share_re_sent(evaluator, launcher, paths, ros_domain, tmp_path):
    stalled = Launcher({**_env(ros_domain), "BEV_POOL_STALL_S": str(3 * TIMEOUT_S)}, log_dir=tmp_path)
    stalled.add("wait#stall", discipline_argv("wait", str(paths["base"]), instance="ws"))
    try:
        live = evaluator.wait_for_instances("wait", 4, 60.0)
        slow = [i for i in live if i.endswith("_ws")][0]
        batch = _batch(200, seed=4)
        res = evaluator.evaluate([("wait", batch)])[0]
        assert res.ok.all(), res.error
        assert np.array_equal(res.outputs["wait_value"], _reference(batch))  # nothing lost, nothing doubled
        st = evaluator.pools["wait"].stats[slow]
        assert st.failures == 1 and st.points == 0 and st.reassigned_points >= 1
        assert slow in evaluator.pools["wait"].suspect and evaluator.retried >= 1
        # the next batch goes to the others only
        res = evaluator.evaluate([("wait", _batch(30))])[0]
        assert res.ok.all() and evaluator.pools["wait"].stats[slow].points == 0
    finally:
        stalled.stop()


def test_optimisation_with_an_energy_pool_equals_in_process(rclpy_context, launcher, paths):
    config = load_config(paths["base"])
    res, stats = coordinator_node.run(config, context=rclpy_context, instances={"energy": 2, "wait": 3})
    ref = run_optimization(copy.deepcopy(config), InProcessEvaluator(resolve_disciplines(config)))
    assert res.success == ref.success
    assert res.objective == ref.objective  # bitwise: the pool changes who computes, not what
    assert res.design == ref.design
    assert stats["data_flow_mdas"] > 0  # pools run in data flow, as row shares (docs/scaling.md)
    assert stats["retried"] == 0
    energy = stats["pools"]["energy"]
    assert len(energy) == 2 and all(s["points"] > 0 for s in energy.values()), energy


def test_status_lists_live_instances_with_host_and_throughput(rclpy_context, evaluator):
    import socket

    from bev_mdo.cli.status import format_table
    from bev_mdo.ros.status import collect

    evaluator.wait_for_instances("wait", 3, 60.0)
    evaluator.evaluate([("wait", _batch(90))])
    node = rclpy.create_node("pool_status", context=rclpy_context)
    try:
        rows = [r for r in collect(node, 1.0) if r["discipline"] == "wait"]
    finally:
        node.destroy_node()
    live = {r["instance"] for r in rows if r["live"]}
    assert {f"wait_node_w{k}" for k in range(3)} <= live, rows
    for r in rows:
        if r["instance"] in {f"wait_node_w{k}" for k in range(3)}:
            assert r["host"] == socket.gethostname() and r["points"] >= 1 and r["capacity_points_per_s"] > 0
    assert "wait_node_w0" in format_table(rows)


def test_status_load_is_points_in_the_listening_window_per_second_of_it(rclpy_context, evaluator):
    """PTS/S(NOW) divided by the time between the first and last counters seen, so an idle instance (one
    sample) showed "-", not 0, and a burst was spread over less than the window (docs/scaling.md)."""
    from bev_mdo.ros.status import collect

    evaluator.wait_for_instances("wait", 3, 60.0)
    live = {f"wait_node_w{k}" for k in range(3)}
    node = rclpy.create_node("pool_status_window", context=rclpy_context)
    try:
        idle = [r for r in collect(node, 0.5) if r["instance"] in live]
        burst = threading.Timer(1.0, lambda: evaluator.evaluate([("wait", _batch(90))]))
        burst.start()  # 90 points inside a 4 s window, after the window opened
        try:
            busy = [r for r in collect(node, 4.0) if r["instance"] in live]
        finally:
            burst.join()
    finally:
        node.destroy_node()
    assert len(idle) == 3 and all(r["recent_points_per_s"] == 0.0 for r in idle), idle
    assert sum(r["recent_points_per_s"] for r in busy) == pytest.approx(90 / 4.0, abs=0.2), busy


def test_two_processes_of_one_node_name_are_two_rows_and_a_warning(rclpy_context):
    """Two standalone nodes started with the default name: status showed one row whose pid flipped from call
    to call and whose load was negative (one process's counters minus the other's)."""
    import json

    from rclpy.executors import SingleThreadedExecutor
    from std_msgs.msg import String

    from bev_mdo.cli.status import shared_names
    from bev_mdo.ros.common import NODE_STATS_QOS, NODE_STATS_READER_QOS, NODE_STATS_TOPIC
    from bev_mdo.ros.fastwait import until
    from bev_mdo.ros.status import collect

    node = rclpy.create_node("twin_names", context=rclpy_context)
    probe = rclpy.create_node("twin_names_probe", context=rclpy_context)
    got = set()
    probe.create_subscription(String, NODE_STATS_TOPIC, lambda m: got.add(json.loads(m.data)["pid"]),
                              NODE_STATS_READER_QOS)
    try:
        for pid, points in ((1001, 500), (1002, 20)):  # kept for late joiners, as a node's latest counters
            pub = node.create_publisher(String, NODE_STATS_TOPIC, NODE_STATS_QOS)
            pub.publish(String(data=json.dumps({"discipline": "twin", "instance": "twin_node", "host": "h",
                                                "pid": pid, "counts": {"points": points}, "compute_s": 1.0})))
        executor = SingleThreadedExecutor(context=rclpy_context)
        executor.add_node(probe)
        try:
            assert until(lambda: {1001, 1002} <= got, 30.0, lambda: executor.spin_once(timeout_sec=0.05))
        finally:
            executor.remove_node(probe)
            executor.shutdown()
        rows = [r for r in collect(probe, 0.5) if r["discipline"] == "twin"]
    finally:
        probe.destroy_node()
        node.destroy_node()
    assert sorted((r["pid"], r["points"], r["recent_points_per_s"]) for r in rows) == [(1001, 500, 0.0),
                                                                                       (1002, 20, 0.0)]
    assert shared_names(rows) == ["warning: 2 processes use the instance name twin_node of twin (pid 1001 on h, "
                                  "pid 1002 on h): their answers count as one instance's; give each its own node "
                                  "name (-r __node:=NAME)"]


def test_sigkill_mid_batch_loses_no_design(evaluator, launcher, paths):
    live = evaluator.wait_for_instances("wait", 3, 60.0)
    batch = _batch(600, seed=5)  # 1.2 s of waiting, about 0.4 s per instance
    victim = "wait#1"
    killer = threading.Timer(0.15, lambda: launcher.kill(victim))
    killer.start()
    try:
        before = sum(_points(evaluator).values())
        res = evaluator.evaluate([("wait", batch)])[0]
    finally:
        killer.join()
        launcher.remove(victim)  # a fresh w1 for the tests after this one
        launcher.add(victim, discipline_argv("wait", str(paths["base"]), instance="w1"))
    assert res.ok.all(), res.error
    assert np.array_equal(res.outputs["wait_value"], _reference(batch))
    assert sum(_points(evaluator).values()) - before == 600  # every row accepted exactly once
    dead = [i for i in live if i.endswith("_w1")][0]
    assert evaluator.pools["wait"].stats[dead].failures == 1


def _designs(n, seed=7):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(50, 120, n), rng.uniform(5, 11, n), rng.uniform(20, 40, n)])


def _analyse_flow(ev, config, X):
    """One MDA of the designs X over `ev`; returns (result, the evaluation ids it sent)."""
    from bev_mdo.mdo.driver import build_formulation

    first, flows = ev._next_id, ev.flows
    res = build_formulation(run_settings(config), ev).analyse(X)
    assert ev.flows == flows + 1  # one data-flow MDA, not waves
    return res, range(first, ev._next_id)


def _check_equal(res, config, X):
    from bev_mdo.mdo.driver import build_formulation

    local = build_formulation(config, InProcessEvaluator(resolve_disciplines(config))).analyse(X)
    assert np.array_equal(res.ok, local.ok)
    for k, v in local.values.items():
        assert np.array_equal(res.values[k], v, equal_nan=True), k  # bitwise


def test_data_flow_mda_with_pools_is_split_into_shares(evaluator, paths):
    config = load_config(paths["base"])
    names = BUILTINS + ["wait"]
    evaluator.wait_for_disciplines(names, 60.0)
    evaluator.wait_for_instances("energy", 2, 60.0)
    evaluator.wait_for_instances("wait", 3, 60.0)
    assert evaluator.flow_plan(names) is not None
    shares_before = evaluator.flow_shares
    kept = len(evaluator.accepted)
    X = _designs(60)
    res, eids = _analyse_flow(evaluator, config, X)
    assert res.ok.all(), res.errors
    _check_equal(res, config, X)
    # data flow: each share is ONE request answered by every discipline (waves: one id per discipline)
    accepted = evaluator.accepted[kept:]
    by_eid: dict[int, list] = {}
    for eid, d, inst, _ in accepted:
        by_eid.setdefault(eid, []).append((d, inst))
    assert evaluator.flow_shares - shares_before == 3 == len(by_eid)  # the wait pool of 3 sets the shares
    assert all(sorted(d for d, _ in got) == sorted(names) for got in by_eid.values()), by_eid
    assert set(by_eid) <= set(eids)
    # each pooled discipline's shares went to its own instances, one answer per share
    assert len({i for got in by_eid.values() for d, i in got if d == "wait"}) == 3
    assert len({i for got in by_eid.values() for d, i in got if d == "energy"}) == 2
    assert evaluator.dropped["duplicate"] == 0 and evaluator.dropped["late_share"] == 0
    assert evaluator.counts["energy"] >= 60 and evaluator.counts["wait"] >= 60


def test_data_flow_share_of_a_stalled_instance_is_re_sent(evaluator, paths, ros_domain, tmp_path):
    config = load_config(paths["base"])
    names = BUILTINS + ["wait"]
    stalled = Launcher({**_env(ros_domain), "BEV_POOL_STALL_S": str(3 * TIMEOUT_S)}, log_dir=tmp_path)
    stalled.add("wait#stall", discipline_argv("wait", str(paths["base"]), instance="ws"))
    try:
        evaluator.wait_for_disciplines(names, 60.0)
        live = evaluator.wait_for_instances("wait", 4, 60.0)
        slow = [i for i in live if i.endswith("_ws")][0]
        X = _designs(80, seed=8)
        res, _ = _analyse_flow(evaluator, config, X)
        assert res.ok.all(), res.errors
        _check_equal(res, config, X)  # nothing lost, nothing doubled
        st = evaluator.pools["wait"].stats[slow]
        assert st.failures == 1 and st.points == 0 and st.reassigned_points >= 1
        assert evaluator.retried >= 1
    finally:
        stalled.stop()


def test_pool_data_flow_false_runs_pooled_mdas_in_waves(rclpy_context, launcher, paths):
    config = load_config(paths["waves"])
    names = BUILTINS + ["wait"]
    node = rclpy.create_node("pool_waves", context=rclpy_context)
    ev = RosEvaluator(node, config=config, timeout_s=TIMEOUT_S, retries=3)
    try:
        ev.wait_for_disciplines(names, 60.0)
        ev.wait_for_instances("wait", 3, 60.0)
        from bev_mdo.mdo.driver import build_formulation

        X = _designs(30, seed=9)
        kept = len(ev.accepted)
        res = build_formulation(run_settings(config), ev).analyse(X)
        assert ev.flows == 0 and ev.flow_shares == 0  # no data-flow request
        _check_equal(res, config, X)
        # waves: one evaluation id per discipline, a pooled one split into shares
        waits = [a for a in ev.accepted[kept:] if a[1] == "wait"]
        assert len(waits) == 3 and len({a[0] for a in ev.accepted[kept:]}) == len(ev.accepted[kept:])
    finally:
        ev.close()
        node.destroy_node()
