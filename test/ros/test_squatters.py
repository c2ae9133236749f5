"""Squatters on a run's topics: processes that read or publish the run's topic names with another type.

DDS matches only endpoints of one type, so such a process can neither receive nor send the run's messages:
it cannot change the answer. The run used to count it among the readers its writers had to match, and gave
up after the discovery wait blaming its own recorder ("the run's recorder declared itself but did not match
['/bev_mdo/iteration', ...]", exit 6). Now it leaves them out and names each one it finds in one line
(topic, node, type); the run goes on to its own optimum and its bag holds every iteration.
"""
from __future__ import annotations

import json
import re
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.ros.common import endpoints
from bev_mdo.testing import PYTHON, leaf_config_file, ros_env

ROS_DOMAIN = 214
HERE = Path(__file__).resolve().parent
LEAF = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
READ = ["/bev_mdo/iteration", "/bev_mdo/mda_request", *[f"/bev_mdo/{d}/request" for d in LEAF]]
WRITE = ["/bev_mdo/iteration", "/bev_mdo/result", *[f"/bev_mdo/{d}/mda_result" for d in LEAF]]
WARNING = re.compile(r"warning: node '(squatter_reader|squatter_writer)' (reads|publishes on) (/bev_mdo/\S+) as "
                     r"std_msgs/msg/String, not bev_mdo_msgs/msg/(IterationRecord|EvaluationRequest|EvaluationResult):"
                     r" it cannot exchange messages with this run \(ignored\)")


class _Graph:
    """A node whose graph holds the given endpoints on every topic."""

    def __init__(self, readers, writers):
        self.readers, self.writers = readers, writers

    def get_subscriptions_info_by_topic(self, topic):
        return self.readers

    def get_publishers_info_by_topic(self, topic):
        return self.writers


def _info(node: str, type_name: str, namespace: str = "/"):
    return SimpleNamespace(node_name=node, node_namespace=namespace, topic_type=type_name)


def test_an_endpoint_of_another_type_is_left_out_and_named_once(capsys, monkeypatch):
    from bev_mdo.ros import common
    from bev_mdo_msgs.msg import EvaluationRequest, IterationRecord

    monkeypatch.setattr(common, "_SQUATTERS", set())
    ours, squatter = _info("recorder_1", "bev_mdo_msgs/msg/IterationRecord"), _info("squatter_reader", "std_msgs/msg/String")
    graph = _Graph([ours, squatter], [])
    assert endpoints(graph, "/bev_mdo/iteration", IterationRecord) == [ours]  # without `warn`: silent
    assert capsys.readouterr().err == ""
    for _ in range(3):
        assert endpoints(graph, "/bev_mdo/iteration", IterationRecord, warn=True) == [ours]
    assert endpoints(_Graph([squatter], []), "/bev_mdo/energy/request", EvaluationRequest, warn=True) == []
    lines = capsys.readouterr().err.splitlines()  # one line per squatting node, at the first topic it is found on
    assert lines == ["warning: node 'squatter_reader' reads /bev_mdo/iteration as std_msgs/msg/String, not "
                     "bev_mdo_msgs/msg/IterationRecord: it cannot exchange messages with this run (ignored)"]


def _squatter(env, name: str, kind: str, topics: list[str]) -> subprocess.Popen:
    p = subprocess.Popen([PYTHON, str(HERE / "squatter.py"), name, kind, *topics], env=env, stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    assert p.stdout.readline().strip() == "ready", p.stdout.read()
    return p


def test_squatters_on_every_topic_neither_stall_nor_change_the_run(ros_domain, tmp_path):
    config = leaf_config_file(tmp_path, {"discovery_wait_s": 60.0})
    c = load_config(config)
    ref = run_optimization(c, InProcessEvaluator(resolve_disciplines(c)))
    env = ros_env(ros_domain)
    squatters = [_squatter(env, "squatter_reader", "sub", READ), _squatter(env, "squatter_writer", "pub", WRITE)]
    try:
        p = subprocess.run([PYTHON, "-m", "bev_mdo", "optimize", str(config), "--domain-id", str(ros_domain),
                            "--bag", str(tmp_path / "b"), "--json", "--quiet"], cwd=tmp_path, env=env,
                           capture_output=True, text=True, timeout=300)
    finally:
        for s in squatters:
            s.communicate(input="", timeout=60)  # stdin closed: the squatter stops
    assert p.returncode == 0 and "Traceback" not in p.stderr, p.stderr[-3000:]
    out = json.loads(p.stdout)
    for k, v in ref.design.items():
        assert out["design"][k] == pytest.approx(v, rel=1e-9, abs=1e-9), k
    # what the run found of them (discovery decides whether it found them): each in one line, once
    named = [WARNING.fullmatch(l) for l in p.stderr.splitlines() if "squatter_" in l]
    assert all(named), p.stderr[-3000:]
    assert len({m.group(1) for m in named}) == len(named), p.stderr[-3000:]
    from bev_mdo.bag.history import history

    checks: dict = {}
    rows = history(tmp_path / "b", checks=checks)
    assert [r["iteration"] for r in rows] == list(range(out["iterations"] + 1)) and checks["dropped"] == {}, \
        (len(rows), out["iterations"], checks)
