"""Redundant instances and concurrent runs on one domain.

One set of discipline nodes, with a second instance of `energy` and of `range`
answering every request too. The coordinator takes the first valid answer and drops
the other as a duplicate; the iterates stay exactly the in-process ones. Then three
optimisations with their own run ids (MDF, IDF and MDF from another start) run at
once against the same nodes; each gives the result it gives alone.
"""
from __future__ import annotations

import threading

import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.ros.status import NodeStatsListener  # noqa: E402
from bev_mdo.ros.evaluator import RosEvaluator  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402

BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
DOUBLED = ["energy", "range"]


# This module's own ROS domain, in the 80-89 block of the fault tests (see test/conftest.py).
ROS_DOMAIN = 84


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    # redundancy is the explicit mode (ros.pool: redundant); by default instances share batches (test_pool.py)
    raw["ros"] = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0, "pool": "redundant"}
    p = tmp_path_factory.mktemp("cfg") / "conc.yaml"
    p.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(p)


@pytest.fixture(scope="module")
def launcher(ros_domain, rclpy_context, config_path, tmp_path_factory):
    la = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    try:
        for name in BUILTINS:
            la.add(name, discipline_argv(name, config_path))
        for name in DOUBLED:
            la.add(f"{name}_b", discipline_argv(name, config_path, instance="b"))
        node = rclpy.create_node("wait_for_instances", context=rclpy_context)
        stats = NodeStatsListener(node)
        try:
            assert stats.wait(lambda s: len(s.latest) == len(BUILTINS) + len(DOUBLED), 60), list(stats.latest)
        finally:
            stats.close()
            node.destroy_node()
        yield la
    finally:
        la.stop()
    assert all(n.restarts == 0 for n in la.nodes)


@pytest.fixture
def both_instances_matched(monkeypatch):
    """Runs start only once both instances of each doubled discipline matched the request topic."""
    orig = RosEvaluator.wait_for_disciplines

    def wait(self, names, wait_s, extra_subscribers=0):
        orig(self, [n for n in names if n not in DOUBLED], wait_s, extra_subscribers)
        orig(self, [n for n in names if n in DOUBLED], wait_s, extra_subscribers + 1)

    monkeypatch.setattr(RosEvaluator, "wait_for_disciplines", wait)


def _inprocess(config, **kw):
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


def _same_iterates(a, b, rel=1e-12):
    assert a.feasible == b.feasible
    assert len(a.history) == len(b.history)
    for ra, rb in zip(a.history, b.history):
        for k in ra["design"]:
            assert ra["design"][k] == pytest.approx(rb["design"][k], rel=rel, abs=1e-12)
        assert ra["objective"] == pytest.approx(rb["objective"], rel=rel)


def test_two_instances_first_valid_answer_wins_and_results_are_deterministic(rclpy_context, launcher, config_path,
                                                                             both_instances_matched, monkeypatch):
    evaluators = []
    orig_init = RosEvaluator.__init__

    def init(self, *a, **kw):
        orig_init(self, *a, **kw)
        evaluators.append(self)

    monkeypatch.setattr(RosEvaluator, "__init__", init)
    config = load_config(config_path)
    ref = _inprocess(config)
    runs = [coordinator_node.run(config, context=rclpy_context) for _ in range(2)]
    for (res, stats), ev in zip(runs, evaluators):
        _same_iterates(res, ref)
        assert stats["dropped"].get("duplicate", 0) > 0
        assert stats["dropped"].get("malformed", 0) == 0
        keys = [(a[0], a[1]) for a in ev.accepted]  # (evaluation id, discipline)
        assert len(keys) == len(set(keys))  # one accepted answer per discipline and evaluation, the other dropped
        instances = {a[2] for a in ev.accepted if a[1] == "energy"}
        assert instances <= {"/energy_node", "energy_node_b"}
    _same_iterates(runs[0][0], runs[1][0], rel=0)


def test_three_concurrent_runs_give_their_results_alone(rclpy_context, launcher, config_path):
    config = load_config(config_path)
    variants = {
        "mdf": ({}, {}),
        "idf": ({"formulation": "idf"}, {"formulation": "idf"}),
        "mdf_x0": ({"x0": {"motor_kw": 100.0, "gear_ratio": 6.0, "battery_kwh": 28.0}},
                   {"x0": {"motor_kw": 100.0, "gear_ratio": 6.0, "battery_kwh": 28.0}}),
    }
    alone = {k: _inprocess(config, **local) for k, (_, local) in variants.items()}
    barrier = threading.Barrier(len(variants), timeout=120)
    out, errors = {}, {}

    def worker(key, kw):
        seen = []

        def on_iteration(rec):
            if not seen:  # every run waits at its first iteration: all three are surely in flight together
                seen.append(1)
                barrier.wait()
        try:
            out[key] = coordinator_node.run(config, run_id=f"concurrent-{key}", on_iteration=on_iteration,
                                            context=rclpy_context, **kw)
        except BaseException as exc:  # reported below
            errors[key] = exc
            barrier.abort()

    threads = [threading.Thread(target=worker, args=(k, ros_kw)) for k, (ros_kw, _) in variants.items()]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert not errors, errors
    assert not any(t.is_alive() for t in threads)
    other = 0
    for key, (res, stats) in out.items():
        assert stats["run_id"] == f"concurrent-{key}"
        _same_iterates(res, alone[key])
        assert stats["dropped"].get("malformed", 0) == 0 and stats["dropped"].get("mismatched", 0) == 0
        other += stats["dropped"].get("other_run", 0)
    assert other > 0  # the runs did see each other's results, and ignored them
