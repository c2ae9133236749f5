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
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import plan_processes  # noqa: E402
from bev_mdo.testing import leaf_config_file, ros_env  # noqa: E402

ROS_DOMAIN = 72
BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    ros = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0, "signing": False}
    return leaf_config_file(tmp_path_factory.mktemp("cfg"), ros, "c.yaml")


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
        log = n.log_path.read_text() if n.log_path else n.label
        assert n.restarts == 0 and (n.proc.returncode in (0, -signal.SIGINT) or _hung_in_dds_teardown(log)), log[-2000:]


def _hung_in_dds_teardown(log: str) -> bool:
    """The node served, took the SIGINT and was still inside rcl's node teardown when the launcher dumped its
    stack (SIGUSR1) and killed it: Fast DDS's entity deletion can hang (bev_mdo/stacks.py, seen once in CI
    in `destroy_node`). Bounded by the launcher and harmless to the run; anything else (a traceback, a
    restart, a hang while serving) still fails the fixture."""
    dump = log.rsplit("Current thread", 1)[-1] if "Current thread" in log else ""
    top = dump.splitlines()[1:2]
    return ("Traceback" not in log and bool(top) and "rclpy" in top[0]
            and any(f in top[0] for f in ("destroy_node", "shutdown")))


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

    from bev_mdo.processes import composed_argv

    argv = composed_argv(["energy", "warp_drive"], str(config_path))
    out = subprocess.run(argv, env=ros_env(ros_domain), capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "warp_drive" in out.stderr and "Traceback" not in out.stderr, out.stderr


def test_link_local_wires_sources_composed_in_the_same_process(config_path):
    """Data flow inside a composed process goes by direct call: each consumer knows the sources
    composed with it (their DDS subscriptions are not read), each producer its local consumers."""
    from bev_mdo.ros.composed import link_local, make_nodes

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx, domain_id=0)
    nodes = []
    try:
        config = load_config(config_path)
        nodes = make_nodes(config, ["vehicle_mass", "energy", "range", "cost"], context=ctx)
        link_local(nodes)
        by = {n.discipline_name: n for n in nodes}
        assert by["energy"].local_sources == {"vehicle_mass"} and by["range"].local_sources == {"energy"}
        assert [n.discipline_name for n in by["vehicle_mass"].local_consumers] == ["energy"]
        assert [n.discipline_name for n in by["energy"].local_consumers] == ["range"]
        assert not by["cost"].local_sources and not by["range"].local_consumers
        # a source's subscription stays in the graph but is not served by the wait set
        served = {sub for n in nodes for sub, _ in n.hot_subscriptions()}
        assert by["energy"]._source_subs["vehicle_mass"] not in served
        assert by["range"]._source_subs["energy"] not in served
        # nor served again by the executor that spins the nodes' services: the result came by direct call
        before = dict(by["range"].counts)
        by["range"]._source_subs["energy"].callback(b"any sample")
        assert dict(by["range"].counts) == before
    finally:
        for n in nodes:
            n.destroy_node()
        rclpy.shutdown(context=ctx)


def test_all_composed_and_signed_gives_the_in_process_optimum(ros_domain, rclpy_context, config_path, tmp_path):
    """All six disciplines in one process, results passed inside it by direct call, every message
    signed: the optimum is the in-process one, bit for bit, and nothing was dropped."""
    from bev_mdo.protocol.signing import new_key_file

    raw = yaml.safe_load(config_path.read_text())
    raw["ros"] = {**raw["ros"], "signing": True, "sign_key_file": new_key_file(tmp_path)}
    path = tmp_path / "signed.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    config = load_config(path)
    run_id = f"allcomposed{os.getpid()}"
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path)
    for label, argv in plan_processes(BUILTINS, str(path), compose="all", run_id=run_id):
        launcher.add(label, argv)
    try:
        assert len(launcher.nodes) == 1
        res, stats = coordinator_node.run(config, context=rclpy_context, run_id=run_id)
        ref = run_optimization(copy.deepcopy(config), InProcessEvaluator(resolve_disciplines(config)))
        assert res.objective == ref.objective and res.design == ref.design
        assert stats["data_flow_mdas"] > 0 and stats["retried"] == 0
        # the module's unsigned, unbound nodes share this domain and answer too: only their answers
        # and declarations are dropped, none of ours (no forged, replayed, expired or malformed one)
        ours = {k: v for k, v in stats["dropped"].items()
                if k not in ("unsigned", "info_unsigned", "refused_instance", "other_run")}
        assert not ours, stats["dropped"]
    finally:
        launcher.stop()


def test_an_rcl_error_racing_a_signalled_shutdown_is_a_normal_stop(ros_domain, config_path, monkeypatch):
    """SIGINT shuts the context down between the serve loop's `context.ok()` and its next rcl call, which
    then raises RCLError ("the given context is not valid"): composed_node stops with status 0, as a
    discipline node does, instead of a traceback and status 1 (seen once at a test's teardown)."""
    from bev_mdo.ros import composed

    def serve_until_signalled(nodes):
        rclpy.shutdown()  # what the SIGINT handler does
        raise RuntimeError("failed to initialize wait set: the given context is not valid")

    monkeypatch.setattr(composed, "serve_many", serve_until_signalled)
    args = ["composed_node", "--ros-args", "-p", f"config:={config_path}", "-p", "disciplines:=energy,range"]
    assert composed.main(args) == 0


def test_any_other_error_while_serving_still_fails_loudly(ros_domain, config_path, monkeypatch):
    from bev_mdo.ros import composed

    def broken(nodes):
        raise RuntimeError("a real bug")

    monkeypatch.setattr(composed, "serve_many", broken)
    args = ["composed_node", "--ros-args", "-p", f"config:={config_path}", "-p", "disciplines:=energy"]
    with pytest.raises(RuntimeError, match="a real bug"):
        composed.main(args)
