"""Several discipline nodes in one process (composed_node): same graph, same answers."""
from __future__ import annotations

import copy
import os
import signal
import time

import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.ros.launch import Launcher, plan_processes  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402

ROS_DOMAIN = 72
BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0, "signing": False}
    path = tmp_path_factory.mktemp("cfg") / "c.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def launcher(ros_domain, config_path, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    # two processes: vehicle_mass+energy+range+cost composed, acceleration+motor_speed composed
    for label, argv in plan_processes(BUILTINS, str(config_path),
                                      compose="vehicle_mass+energy+range+cost,acceleration+motor_speed"):
        launcher.add(label, argv)
    yield launcher
    launcher.stop()
    for n in launcher.nodes:
        assert n.restarts == 0 and n.proc.returncode in (0, -signal.SIGINT), (
            n.log_path.read_text()[-2000:] if n.log_path else n.label)


def test_two_processes_serve_six_nodes_and_the_optimum_equals_in_process(rclpy_context, launcher, config_path):
    assert len(launcher.nodes) == 2
    config = load_config(config_path)
    res, stats = coordinator_node.run(config, context=rclpy_context)
    ref = run_optimization(copy.deepcopy(config), InProcessEvaluator(resolve_disciplines(config)))
    assert res.objective == ref.objective and res.design == ref.design
    assert stats["data_flow_mdas"] > 0  # composed nodes still talk over topics, data flow included
    probe = rclpy.create_node("compose_probe", context=rclpy_context)
    try:
        want = {f"{d}_node" for d in BUILTINS}
        deadline = time.monotonic() + 30.0
        while not want <= (names := {n for n, _ns in probe.get_node_names_and_namespaces()}):
            if time.monotonic() > deadline:
                break
            time.sleep(0.05)  # graph discovery happens in DDS threads
        assert want <= names, names  # every discipline is its own node in the graph
    finally:
        probe.destroy_node()
    pids = {n.proc.pid for n in launcher.nodes}
    assert len(pids) == 2 and all(os.path.exists(f"/proc/{p}") for p in pids)


def test_composed_node_rejects_an_unknown_discipline(ros_domain, config_path):
    import subprocess

    from bev_mdo.ros.launch import composed_argv

    argv = composed_argv(["energy", "warp_drive"], str(config_path))
    out = subprocess.run(argv, env=ros_env(ros_domain), capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "warp_drive" in out.stderr and "Traceback" not in out.stderr, out.stderr
