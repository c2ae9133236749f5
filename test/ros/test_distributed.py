"""Distributed MDO over ROS: one process per discipline, the coordinator in this process.

One set of node processes serves the whole module; each test runs its own
coordinator (own run id) against it.
"""
from __future__ import annotations

import copy
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

import rclpy

from bev_mdo.config import load_config, resolve_disciplines, run_settings  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.ros.evaluator import DisciplineMissing  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.testing import REPO, assert_same_iterates, ros_env  # noqa: E402

BASE = REPO / "config" / "leaf_nedc.yaml"
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))  # the coordinator validates the config, so it imports the test disciplines too
BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


def _write(path: Path, cfg: dict) -> str:
    path.write_text(yaml.safe_dump(cfg, sort_keys=False))
    return str(path)


@pytest.fixture(scope="module")
def configs(tmp_path_factory):
    d = tmp_path_factory.mktemp("cfg")
    raw = yaml.safe_load(BASE.read_text())
    raw["ros"] = {"timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0}
    base = _write(d / "base.yaml", raw)
    slow = copy.deepcopy(raw)
    slow["disciplines"] = [n for n in BUILTINS if n != "range"] + [
        {"name": "slow_range", "class": "slow_discipline:SlowFirstRange", "options": {"delay_s": 1.5}}]
    slow["ros"] = {"timeout_s": 0.5, "retries": 3, "discovery_wait_s": 60.0}
    top = copy.deepcopy(raw)
    top["disciplines"] = BUILTINS + [
        {"name": "top_speed", "class": "examples.top_speed:TopSpeed", "options": {"motor_max_speed_rad_s": 1100.0}}]
    top["problem"]["constraints"]["top_speed_kmh"] = {"lower": 150.0}
    missing = copy.deepcopy(raw)
    missing["disciplines"] = BUILTINS + [
        {"name": "top_speed_absent", "class": "examples.top_speed:TopSpeed", "options": {}}]
    missing["ros"] = {"discovery_wait_s": 1.0}
    return {"base": base, "slow": _write(d / "slow.yaml", slow), "top": _write(d / "top.yaml", top),
            "missing": _write(d / "missing.yaml", missing)}


@pytest.fixture(scope="module")
def nodes(ros_domain, configs, tmp_path_factory):
    env = ros_env(ros_domain)
    env["PYTHONPATH"] = f"{HERE}:{REPO}:{env['PYTHONPATH']}"
    launcher = Launcher(env, log_dir=tmp_path_factory.mktemp("logs"))
    for name in BUILTINS:
        launcher.add(name, discipline_argv(name, configs["base"]))
    launcher.add("slow_range", discipline_argv("slow_range", configs["slow"]))
    launcher.add("top_speed", discipline_argv("top_speed", configs["top"]))
    yield launcher
    launcher.stop()
    for n in launcher.nodes:  # a crashed node would show here, not just as a timeout
        assert n.restarts == 0, f"{n.label} died: {n.log_path.read_text()[-2000:] if n.log_path else ''}"


def _ros_run(rclpy_context, path, **kw):
    return coordinator_node.run(load_config(path), context=rclpy_context, **kw)


def _inprocess(path, **kw):
    config = load_config(path)
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


def test_mdf_over_ros_gives_the_in_process_iterates(rclpy_context, nodes, configs):
    ros, stats = _ros_run(rclpy_context, configs["base"])
    local = _inprocess(configs["base"])
    assert ros.feasible and local.feasible
    assert_same_iterates(ros, local)
    assert ros.mda_evaluations == local.mda_evaluations
    assert stats["retried"] == 0
    # every MDA was one data-flow request (the point and its FD stencil in one batch)
    assert stats["data_flow_mdas"] == ros.batches > 0


def test_mda_falls_back_to_waves_when_a_node_reads_a_coupling_elsewhere(rclpy_context, nodes, configs):
    """A node whose declared coupling source differs from the coordinator's graph gets no
    data-flow request: the MDA runs in waves, with the same values and counts."""
    from bev_mdo.mdo.driver import build_formulation

    config = load_config(configs["base"])
    node = coordinator_node.CoordinatorNode(config, context=rclpy_context, node_name="fallback_probe")
    try:
        ev = node.evaluator
        ev.wait_for_disciplines(BUILTINS, 60.0)
        X = np.array([[80.0, 8.0, 24.0], [60.0, 5.0, 21.0], [120.0, 11.0, 30.0]])
        flow = build_formulation(run_settings(config), ev).analyse(X)
        assert ev.flows == 1
        ev.coupling_sources["energy"] = {"vehicle_mass_kg": "somewhere_else"}
        ev._flow_plans.clear()
        waves = build_formulation(run_settings(config), ev).analyse(X)
        assert ev.flows == 1  # unchanged: no data-flow request this time
        local = build_formulation(config, InProcessEvaluator(resolve_disciplines(config))).analyse(X)
        for res in (flow, waves):
            assert res.ok.all()
            for k, v in local.values.items():
                np.testing.assert_array_equal(res.values[k], v, err_msg=k)
    finally:
        node.evaluator.close()
        node.destroy_node()


def test_idf_over_ros_reaches_the_mdf_optimum(rclpy_context, nodes, configs):
    idf, _ = _ros_run(rclpy_context, configs["base"], formulation="idf")
    mdf = _inprocess(configs["base"])
    assert idf.feasible and idf.formulation == "idf"
    for k, v in mdf.design.items():
        assert idf.design[k] == pytest.approx(v, rel=1e-4)


def test_a_stalled_discipline_is_retried_and_the_optimum_is_unchanged(rclpy_context, nodes, configs):
    res, stats = _ros_run(rclpy_context, configs["slow"])
    ref = _inprocess(configs["base"])
    assert stats["retried"] >= 1
    # the stalled first answer arrives late and is dropped as a duplicate, never reused
    assert stats["dropped"].get("duplicate", 0) >= 1
    assert res.feasible
    for k, v in ref.design.items():
        assert res.design[k] == pytest.approx(v, rel=1e-9)


def test_a_user_discipline_runs_as_a_node_and_constrains_the_optimum(rclpy_context, nodes, configs):
    res, _ = _ros_run(rclpy_context, configs["top"])
    local = _inprocess(configs["top"])
    assert res.feasible
    assert res.outputs["top_speed_kmh"] >= 150.0 - 1e-6
    for k, v in local.design.items():
        assert res.design[k] == pytest.approx(v, rel=1e-9)
    base = _inprocess(configs["base"])  # without the constraint the optimum is slower than 150 km/h
    top_free = base.outputs.get("top_speed_kmh")
    assert top_free is None  # not computed without the discipline
    assert res.design != base.design


def test_a_missing_discipline_is_named(rclpy_context, nodes, configs):
    with pytest.raises(DisciplineMissing, match="top_speed_absent"):
        _ros_run(rclpy_context, configs["missing"])


def test_evaluate_and_sensitivity_over_ros_print_what_in_process_prints(nodes, configs, ros_domain, tmp_path,
                                                                        capsys):
    import json as _json

    from bev_mdo.cli import main

    raw = yaml.safe_load(Path(configs["base"]).read_text())
    raw["ros"] = {**raw.get("ros", {}), "domain_id": ros_domain}
    path = _write(tmp_path / "domain.yaml", raw)
    for argv in (["evaluate", path, "--set", "motor_kw=70,gear_ratio=9,battery_kwh=22", "--json"],
                 ["sensitivity", path, "--at", "motor_kw=80,gear_ratio=8,battery_kwh=24", "--order", "2", "--json"]):
        assert main(argv + ["--attach"]) == 0  # the nodes of the fixture
        over_ros = _json.loads(capsys.readouterr().out)
        assert main(argv + ["--transport", "inprocess"]) == 0
        local = _json.loads(capsys.readouterr().out)
        assert over_ros == local


def test_bad_data_flow_requests_are_rejected_and_the_nodes_keep_serving(rclpy_context, nodes, configs):
    """Missing inputs, a wrong batch length and undecodable bytes on /bev_mdo/mda_request (read
    by the disciplines without sources): the node answers REJECTED (or counts the bytes it
    cannot decode) and keeps serving; a consumer of a rejected source answers no point."""
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo import protocol
    from bev_mdo.ros.common import MDA_REQUEST_TOPIC, MDA_RESULT_QOS, REQUEST_QOS, mda_result_topic, stamp
    from bev_mdo.ros.status import NodeStatsListener
    from bev_mdo.binding import tag_for
    from bev_mdo_msgs.msg import EvaluationRequest, EvaluationResult

    base_config = load_config(configs["base"])
    probe = rclpy.create_node("flow_fuzz_probe", context=rclpy_context)
    got = {"vehicle_mass": [], "energy": []}
    pub = probe.create_publisher(EvaluationRequest, MDA_REQUEST_TOPIC, REQUEST_QOS)
    subs = [probe.create_subscription(EvaluationResult, mda_result_topic(d),
                                      lambda data, d=d: got[d].append(protocol.decode_result(data)), MDA_RESULT_QOS,
                                      raw=True) for d in got]
    stats = NodeStatsListener(probe)
    try:
        assert stats.wait(lambda s: all(sub.get_publisher_count() >= 1 for sub in subs) and s.seen("vehicle_mass")
                          and pub.get_subscription_count() >= 3, 60.0)  # mass, motor_speed, cost read it
        before = stats.counts("vehicle_mass")

        def send(eid, flow, cols, batch_size=None):
            req = protocol.request("flow-fuzz", eid, "", flow=flow)
            req.header.frame_id = tag_for(base_config, flow)
            req.inputs = protocol.batch(cols)
            if batch_size is not None:
                req.inputs.batch_size = batch_size
            stamp(req.header)
            pub.publish(protocol.encode_request(req))

        # vehicle_mass without battery_kwh; energy, its consumer, then has no point to evaluate
        send(1, ["vehicle_mass", "energy"], {"motor_kw": np.array([80.0]), "gear_ratio": np.array([8.0])})
        # a batch size that does not match the values
        send(2, ["vehicle_mass"], {"motor_kw": np.array([80.0, 90.0]), "battery_kwh": np.array([24.0, 25.0])},
             batch_size=3)
        pub.publish(b"\x00\x01\x00\x00\xff\xff\xff\x7f")  # a header cut short
        # a good one: mass and energy, energy taking gear_ratio from mass's forwarded columns
        send(3, ["vehicle_mass", "energy"], {"motor_kw": np.array([80.0]), "battery_kwh": np.array([24.0]),
                                              "gear_ratio": np.array([8.0])})

        def mine(d):
            return {int(r.evaluation_id): r for r in got[d] if r.run_id == "flow-fuzz"}

        assert stats.wait(lambda s: len(mine("vehicle_mass")) >= 3 and len(mine("energy")) >= 2
                          and s.counts("vehicle_mass")["rejected.undecodable"] > before["rejected.undecodable"],
                          30.0), (got, stats.counts("vehicle_mass"))
        mass, energy = mine("vehicle_mass"), mine("energy")
        assert mass[1].status == EvaluationResult.STATUS_REJECTED and "missing inputs" in mass[1].error
        assert energy[1].point_ok.tolist() in ([], [False])  # nothing evaluated downstream of a rejection
        assert mass[2].status == EvaluationResult.STATUS_REJECTED
        assert mass[3].status == energy[3].status == EvaluationResult.STATUS_OK
        assert energy[3].flow == ["vehicle_mass", "energy"] and "gear_ratio" in energy[3].outputs.names
        after = stats.counts("vehicle_mass")
        assert after["rejected.missing_inputs"] - before["rejected.missing_inputs"] == 1
        assert after["rejected.malformed"] - before["rejected.malformed"] == 1
    finally:
        stats.close()
        probe.destroy_node()
    # the nodes still serve a whole data-flow MDA
    config = load_config(configs["base"])
    node = coordinator_node.CoordinatorNode(config, context=rclpy_context, node_name="after_fuzz")
    try:
        node.evaluator.wait_for_disciplines(BUILTINS, 60.0)
        res = build_formulation(run_settings(config), node.evaluator).analyse(np.array([[80.0, 8.0, 24.0]]))
        assert res.ok.all() and node.evaluator.flows == 1
    finally:
        node.evaluator.close()
        node.destroy_node()
