"""Foundation: the ros2-run layout, message round trips, and cross-process messaging."""
from __future__ import annotations

import os
import subprocess
import textwrap

import numpy as np
import pytest

from bev_mdo.testing import PYTHON, REPO, ros_env

from rclpy.serialization import deserialize_message, serialize_message  # noqa: E402

from bev_mdo.processes import DISCIPLINE_EXES, OTHER_EXES  # noqa: E402
from bev_mdo import protocol  # noqa: E402
from bev_mdo_msgs.msg import (  # noqa: E402
    DisciplineInfo, EvaluationRequest, EvaluationResult, IterationRecord, NamedArray,
)

EXES = sorted([*DISCIPLINE_EXES, *OTHER_EXES])


def test_ros2_run_layout_resolves_every_executable():
    from ament_index_python.packages import get_package_prefix, get_package_share_directory

    prefix = get_package_prefix("bev_mdo")
    assert os.path.isfile(os.path.join(get_package_share_directory("bev_mdo"), "package.xml"))
    for exe in EXES:
        path = os.path.join(prefix, "lib", "bev_mdo", exe)
        assert os.path.isfile(path), path
        assert os.access(path, os.X_OK), f"{path} is not executable"


def test_unknown_executable_is_refused():
    out = subprocess.run([PYTHON, "-m", "bev_mdo.ros.run", "no_such_node"], capture_output=True, text=True,
                         env=ros_env(0))
    assert out.returncode == 2 and "unknown executable" in out.stderr


def _sample_messages():
    req = EvaluationRequest()
    req.run_id = "run-1"
    req.evaluation_id = 42
    req.sequence = 7
    req.iteration = 3
    req.attempt = 1
    req.discipline = "energy"
    protocol.to_named_array({"vehicle_mass_kg": np.array([1500.0, 1600.0]), "gear_ratio": np.array([8.0, 9.5])},
                        req.inputs)
    res = EvaluationResult()
    res.run_id, res.evaluation_id, res.discipline, res.instance = "run-1", 42, "energy", "/energy_node"
    res.status = EvaluationResult.STATUS_ERROR
    res.error = "energy: non-finite output at point 1"
    res.point_ok = [True, False]
    protocol.to_named_array({"energy_wh_per_km": np.array([120.5, np.nan])}, res.outputs)
    res.compute_time_s = 1.5e-5
    it = IterationRecord()
    it.run_id, it.iteration, it.formulation, it.optimizer = "run-1", 5, "mdf", "SLSQP"
    protocol.to_named_array({"motor_kw": np.array([80.0])}, it.design)
    it.objective_name, it.objective, it.max_violation, it.feasible = "energy_wh_per_km", 110.25, 0.0, True
    it.discipline_names, it.discipline_evaluations = ["energy", "range"], [10, 12]
    info = DisciplineInfo()
    info.discipline, info.inputs, info.outputs, info.parameters = "range", ["a_kw"], ["b_km"], ["c_m2"]
    na = NamedArray()
    protocol.to_named_array({"x": np.arange(3.0), "y": -np.arange(3.0)}, na)
    return [req, res, it, info, na]


@pytest.mark.parametrize("msg", _sample_messages(), ids=lambda m: type(m).__name__)
def test_every_message_round_trips_through_serialization(msg):
    back = deserialize_message(serialize_message(msg), type(msg))
    for field in msg.get_fields_and_field_types():
        a, b = getattr(msg, field), getattr(back, field)
        if isinstance(a, NamedArray):
            da, db = protocol.from_named_array(a), protocol.from_named_array(b)
            assert list(da) == list(db)
            for k in da:
                np.testing.assert_array_equal(da[k], db[k])
        elif hasattr(a, "tolist"):
            assert list(a) == list(b), field
        else:
            assert a == b, field


def test_named_array_rejects_malformed_batches():
    bad = NamedArray()
    bad.names, bad.batch_size, bad.values = ["a", "b"], 3, [1.0, 2.0]
    with pytest.raises(protocol.WireError, match="values"):
        protocol.from_named_array(bad)
    bad.names, bad.batch_size, bad.values = ["a", "a"], 1, [1.0, 2.0]
    with pytest.raises(protocol.WireError, match="duplicate"):
        protocol.from_named_array(bad)
    bad.names, bad.batch_size, bad.values = ["not a name!"], 1, [1.0]
    with pytest.raises(protocol.WireError, match="bad variable name"):
        protocol.from_named_array(bad)


PUBLISHER = textwrap.dedent(
    """
    import sys, rclpy
    from rclpy.node import Node
    from bev_mdo.ros.common import ITERATION_QOS
    from bev_mdo_msgs.msg import IterationRecord
    rclpy.init()
    node = Node("foundation_pub")
    pub = node.create_publisher(IterationRecord, "/bev_mdo/test_foundation", ITERATION_QOS)
    while pub.get_subscription_count() < 1:      # wait for discovery, no sleep
        rclpy.spin_once(node, timeout_sec=0.05)
    msg = IterationRecord(); msg.run_id = "cross-process"; msg.iteration = 17; msg.objective = 101.5
    pub.publish(msg)
    # stay until the subscriber closes our stdin, so the message is surely delivered
    sys.stdin.read()
    node.destroy_node(); rclpy.shutdown()
    """
)


def test_custom_message_crosses_processes(rclpy_context, ros_domain):
    from rclpy.node import Node

    from bev_mdo.ros.common import ITERATION_QOS

    node = Node("foundation_sub", context=rclpy_context)
    got = []
    node.create_subscription(IterationRecord, "/bev_mdo/test_foundation", got.append, ITERATION_QOS)
    child = subprocess.Popen([PYTHON, "-c", PUBLISHER], env=ros_env(ros_domain), stdin=subprocess.PIPE)
    try:
        from rclpy.executors import SingleThreadedExecutor

        ex = SingleThreadedExecutor(context=rclpy_context)
        ex.add_node(node)
        for _ in range(2000):  # bounded: at most ~100 s of 50 ms waits
            if got or child.poll() is not None:
                break
            ex.spin_once(timeout_sec=0.05)
        assert got, f"no message received (publisher exit code {child.poll()})"
        assert got[0].run_id == "cross-process" and got[0].iteration == 17 and got[0].objective == 101.5
    finally:
        child.stdin.close()
        child.wait(timeout=30)
        node.destroy_node()


def test_a_node_keeps_the_vehicle_choices_of_its_config(rclpy_context):
    """The node's vehicle.<key> parameters cover the numbers; mass_model (a choice) must survive too."""
    import yaml

    from bev_mdo.config import load_config, resolve_disciplines
    from bev_mdo.mdo.discipline import run_discipline
    from bev_mdo.ros.discipline_node import DisciplineNode

    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["vehicle"]["mass_model"] = "compounding"
    config = load_config(raw)
    node = DisciplineNode("vehicle_mass", config=config, context=rclpy_context, node_name="choices_probe")
    try:
        x = {"motor_kw": np.array([120.0]), "battery_kwh": np.array([30.0])}
        here = {d.name: d for d in resolve_disciplines(config)}["vehicle_mass"]
        ch7 = {d.name: d for d in resolve_disciplines(load_config(REPO / "config" / "leaf_nedc.yaml"))}
        got = run_discipline(node.discipline, x).outputs["vehicle_mass_kg"]
        np.testing.assert_array_equal(got, run_discipline(here, x).outputs["vehicle_mass_kg"])
        assert got[0] != run_discipline(ch7["vehicle_mass"], x).outputs["vehicle_mass_kg"][0]
    finally:
        node.destroy_node()


def test_a_vehicle_parameter_set_on_the_nodes_command_line_changes_what_it_computes(rclpy_context):
    """-p vehicle.glider_kg:=... makes a config of the node's own: its mass answers and its fingerprint
    follow the new value, and the run's config is left as it was."""
    from rclpy.parameter import Parameter

    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.discipline import run_discipline
    from bev_mdo.ros.discipline_node import DisciplineNode

    config = RunConfig.load(REPO / "config" / "leaf_nedc.yaml")
    plain_node = DisciplineNode("vehicle_mass", config=config, context=rclpy_context, node_name="glider_plain")
    heavy = DisciplineNode("vehicle_mass", config=config, context=rclpy_context, node_name="glider_heavy",
                           parameter_overrides=[Parameter("vehicle.glider_kg", value=1369.64)])
    try:
        x = {"motor_kw": np.array([80.0]), "battery_kwh": np.array([24.0])}
        base = run_discipline(plain_node.discipline, x).outputs["vehicle_mass_kg"][0]
        got = run_discipline(heavy.discipline, x).outputs["vehicle_mass_kg"][0]
        assert got == pytest.approx(base + 100.0, rel=1e-12)
        assert heavy.fingerprint != plain_node.fingerprint
        assert config["vehicle"]["glider_kg"] == 1269.64
    finally:
        heavy.destroy_node()
        plain_node.destroy_node()
