"""Eight runs started together on one domain, with a stranger reading every topic.

Eight `bev-mdo optimize ... --bag` processes start at once on this (2-core) host: four different
configurations, two runs each, on one ROS domain, while a foreign process subscribes to every
topic the runs use (so a count of subscribers says nothing about a run's recorder). Each run
must start (start-up waits for progress, not for a clock), wait for its OWN recorder (known by
its signed declaration) and report exactly the optimum it reports alone (1e-9). Each bag holds
exactly its own run's iteration records, each iteration once, with the in-process iterates, and
no record of another run. Afterwards the ROS logs are in each run's folder, ~/.ros/log holds
nothing new, and /dev/shm holds no Fast DDS file of a process that is gone.
"""
from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.shm import remove_orphans
from bev_mdo.testing import PYTHON, REPO, ros_env

NAMES = ["vehicle_mass", "energy", "range"]
VARIANTS = {"leaf": None, "drag08": ("vehicle", "drag_area_m2", 0.8), "wltc": ("cycle", "name", "wltc_class3"),
            "range230": ("problem", "constraints", {"range_km": {"lower": 230}})}
RUNS_PER_CONFIG = 2
RUN_TIMEOUT_S = 600  # bounds the test on a loaded host; a run alone takes seconds

# Subscribes (reliable, deep) to every topic of the runs and says "ready" once it did.
FOREIGN = """
import sys, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, HistoryPolicy
from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult, IterationRecord
rclpy.init()
node = rclpy.create_node("stranger")
qos = QoSProfile(reliability=ReliabilityPolicy.RELIABLE, history=HistoryPolicy.KEEP_LAST, depth=1000)
topics = {"/bev_mdo/iteration": IterationRecord, "/bev_mdo/result": EvaluationResult,
          "/bev_mdo/mda_request": EvaluationRequest}
for d in sys.argv[1:]:
    topics[f"/bev_mdo/{d}/request"] = EvaluationRequest
    topics[f"/bev_mdo/{d}/mda_result"] = EvaluationResult
subs = [node.create_subscription(t, name, lambda m: None, qos, raw=True) for name, t in topics.items()]
print("ready", flush=True)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
    pass
"""


def _raw(change):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = list(NAMES)
    raw["problem"]["constraints"] = {"range_km": {"lower": 210}}
    # a box whose designs all follow the cycle: with range alone the optimum ran to 40 kW at 11:1, which
    # cannot reach the NEDC's 120 km/h (motor over its speed limit) nor follow the WLTC (verdict infeasible)
    raw["problem"]["design_variables"]["motor_kw"]["lower"] = 60.0
    raw["problem"]["design_variables"]["gear_ratio"]["upper"] = 9.0
    raw["optimizer"] = {"name": "SLSQP", "options": {"maxiter": 6}}
    # start-up waits with the default bound (ros.discovery_wait_s, 60 s without progress): eight runs
    # starting together on a loaded host must all start with it
    if change:
        raw[change[0]][change[1]] = change[2]
    return raw


def _iterations(bag: Path) -> list:
    from bev_mdo.bag.reader import open_bag

    b = open_bag(bag)
    return [msg for _, msg in b.decoded(["/bev_mdo/iteration"])]


def _shm_orphans(before: set[str]) -> list[str]:
    """New Fast DDS lock files in /dev/shm that no live process holds."""
    import fcntl

    out = []
    for name in sorted(set(os.listdir("/dev/shm")) - before):
        if not (name.startswith(("fastrtps_", "fast_datasharing_")) and name.endswith(("_el", "_sl"))):
            continue
        try:
            with open(Path("/dev/shm") / name, "rb") as f:
                fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
                out.append(name)
        except OSError:
            pass  # held by a live process, or gone
    return out


def test_eight_runs_of_four_configs_on_one_domain_each_record_only_their_own(ros_domain, tmp_path):
    configs, references = {}, {}
    for name, change in VARIANTS.items():
        p = tmp_path / f"{name}.yaml"
        p.write_text(yaml.safe_dump(_raw(change), sort_keys=False))
        configs[name] = p
        recs = []
        c = load_config(p)
        references[name] = (run_optimization(c, InProcessEvaluator(resolve_disciplines(c)), callback=recs.append),
                            recs)
    optima = sorted(r.objective for r, _ in references.values())
    assert min(b - a for a, b in zip(optima, optima[1:])) > 1e-3  # the optima differ: a mix-up would show

    ros_home_log = Path.home() / ".ros" / "log"
    logs_before = set(os.listdir(ros_home_log)) if ros_home_log.is_dir() else set()
    shm_before = set(os.listdir("/dev/shm"))
    env = ros_env(ros_domain)
    env.pop("ROS_LOG_DIR", None)
    stranger_env = {**env, "ROS_LOG_DIR": str(tmp_path / "stranger_log")}
    stranger = subprocess.Popen([PYTHON, "-c", FOREIGN, *NAMES], env=stranger_env, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
    procs = {}
    try:
        assert stranger.stdout.readline().strip() == "ready"
        for name in VARIANTS:
            for k in range(RUNS_PER_CONFIG):
                run = f"{name}_{k}"
                procs[run] = (name, subprocess.Popen(
                    [PYTHON, "-m", "bev_mdo", "optimize", str(configs[name]), "--domain-id", str(ros_domain),
                     "--bag", str(tmp_path / "bags" / run), "--json", "--quiet"],
                    cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True))
        outs, hung, deadline = {}, [], time.monotonic() + RUN_TIMEOUT_S
        for run, (name, p) in procs.items():
            try:
                out, err = p.communicate(timeout=max(1.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.send_signal(signal.SIGUSR1)  # every thread's stack (bev_mdo.stacks), then kill
                p.kill()
                out, err = p.communicate()
            # the one failure allowed: a participant hung in the middleware at the process's exit (a Fast DDS
            # deadlock under this load, once in a local run of this test), after the result was printed
            # (stacks.defer_teardowns): bounded by SIGALRM, its stacks show the deferred teardown
            hung_at_exit = p.returncode == -signal.SIGALRM and "_run_deferred" in err and bool(out.strip())
            assert p.returncode == 0 or hung_at_exit, f"{run}: exit {p.returncode}\n{err[-4000:]}"
            outs[run] = json.loads(out)
            if hung_at_exit:
                hung.append(run)
    finally:
        for _, p in procs.values():
            if p.poll() is None:
                p.kill()
                p.wait()
        stranger.send_signal(signal.SIGINT)
        try:
            stranger.wait(timeout=10)
        except subprocess.TimeoutExpired:
            stranger.kill()
            stranger.wait()

    for run, out in outs.items():
        name = procs[run][0]
        ref, recs = references[name]
        assert out["design"] == pytest.approx(ref.design, rel=1e-9, abs=1e-9), run
        assert out["objective"] == pytest.approx(ref.objective, rel=1e-9), run
        assert out["signing"] == "per-run key"
        got = _iterations(tmp_path / "bags" / run)
        assert {m.run_id for m in got} == {out["run_id"]}, run  # its own records, no other run's
        assert [m.iteration for m in got] == [r["iteration"] for r in recs], run  # each iteration, once
        assert [m.objective for m in got] == pytest.approx([r["objective"] for r in recs], rel=1e-9), run
        # the run's ROS logs (its nodes' and its own) are in its folder
        assert list((tmp_path / "bags" / run / "logs" / "ros").glob("*.log")), run

    logs_after = set(os.listdir(ros_home_log)) if ros_home_log.is_dir() else set()
    assert not logs_after - logs_before, sorted(logs_after - logs_before)[:5]
    if hung:  # a process ended by SIGALRM leaves its Fast DDS files; the next start removes them (bev_mdo.shm)
        print(f"teardown hung at exit after the result: {hung}")
        remove_orphans()
    assert not _shm_orphans(shm_before)
