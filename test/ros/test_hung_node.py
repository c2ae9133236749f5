"""A node that hangs with its process alive is restarted, and the run still finds its optimum.

Under overload, Fast DDS can deadlock a participant (eProsima/Fast-DDS#6502, caught with gdb in a
node of the three-concurrent-runs test): the process lives, and the node never answers or
announces itself again. Here vehicle_mass is frozen with SIGSTOP once the first iteration is
printed, which looks the same from outside: the process lives and its participant is silent.
The launcher's watchdog sees it leave the ROS graph, kills it, and the supervisor restarts it. The
coordinator's retries reach the new process, and the run ends with exit 0, the in-process
optimum, and the hang named on stderr and in the summary.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time

import pytest

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.testing import PYTHON, child_processes, leaf_config_file, ros_env


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    # the shipped ros.timeout_s and ros.retries: their budget must cover the lease (12 s), the
    # watchdog's 7 s and a restart (docs/security.md)
    return str(leaf_config_file(tmp_path_factory.mktemp("hung"), {}, "hung.yaml"))


def test_a_frozen_node_is_killed_restarted_and_the_run_finds_its_optimum(config_path, ros_domain, tmp_path):
    config = load_config(config_path)
    ref = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    p = subprocess.Popen([PYTHON, "-m", "bev_mdo", "optimize", config_path, "--compose", "none", "--domain-id", str(ros_domain),
                          "--no-record", "--json"], cwd=tmp_path, env=ros_env(ros_domain), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    frozen, err_lines = [], []
    deadline = time.monotonic() + 400
    try:
        for line in p.stderr:
            err_lines.append(line)
            if not frozen and line.startswith("iter"):
                for pid, cmd in child_processes(p.pid).items():
                    if "vehicle_mass_node" in cmd:
                        os.kill(pid, signal.SIGSTOP)  # a child of the run we started, by its id
                        frozen.append(pid)
                assert len(frozen) == 1, child_processes(p.pid)
            if time.monotonic() > deadline:
                break
    finally:
        if p.poll() is None and time.monotonic() > deadline:
            p.kill()
        for pid in frozen:  # never leave a stopped process behind, whatever happened
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
    out = p.stdout.read()
    p.wait(timeout=60)
    err = "".join(err_lines)
    assert p.returncode == 0, err[-4000:]
    res = json.loads(out)
    for k, v in ref.design.items():
        assert res["design"][k] == pytest.approx(v, rel=1e-6), (k, res.get("discipline_errors"), err[-3000:])
    assert res["node_hangs"] == {"vehicle_mass": 1}
    assert res["node_restarts"] == {"vehicle_mass": 1}
    assert "vehicle_mass left the ROS graph" in err and "hung middleware" in err
    assert res["retried_requests"] > 0  # the frozen node's requests were re-sent to its successor
