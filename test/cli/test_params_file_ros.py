"""`--params-file` works for the nodes as docs/ros2-run.md says: the shipped example parses as a ROS
parameters file, and a generic discipline node given only a parameters file (config + discipline)
declares the discipline that file names."""
from __future__ import annotations

import sys

import pytest
import yaml


from bev_mdo.config import load_config  # noqa: E402
from bev_mdo.ros import coordinator_node  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.testing import REPO, ros_env  # noqa: E402

ROS_DOMAIN = 58
SHIPPED = REPO / "config" / "params" / "leaf_nedc_nodes.yaml"


def test_the_shipped_parameters_file_names_declared_parameters():
    doc = yaml.safe_load(SHIPPED.read_text())
    assert doc["/**"]["ros__parameters"]["config"] == "config/leaf_nedc.yaml"
    assert (REPO / doc["/**"]["ros__parameters"]["config"]).is_file()
    assert set(doc["coordinator_node"]["ros__parameters"]) <= {"config", "formulation", "optimizer", "run_id",
                                                                "recorders"}


def test_a_node_started_with_only_a_parameters_file_serves_what_it_names(ros_domain, rclpy_context, tmp_path):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                          {"name": "top_speed", "class": "examples.top_speed:TopSpeed",
                           "options": {"motor_max_speed_rad_s": 1100.0}}]
    raw["ros"] = {"domain_id": ros_domain}
    cfg = tmp_path / "top.yaml"
    cfg.write_text(yaml.safe_dump(raw, sort_keys=False))
    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump({"/**": {"ros__parameters": {"config": str(cfg), "discipline": "top_speed"}}}))
    env = ros_env(ros_domain)
    env["PYTHONPATH"] = f"{REPO}:{env.get('PYTHONPATH', '')}"
    la = Launcher(env, log_dir=tmp_path / "logs")
    try:
        node = la.add("top_speed", [sys.executable, "-m", "bev_mdo.ros.run", "discipline_node", "--ros-args",
                                    "--params-file", str(params)])
        coord = coordinator_node.CoordinatorNode(load_config(str(cfg)), context=rclpy_context,
                                                 node_name="params_probe")
        try:
            coord.evaluator.wait_for_disciplines(["top_speed"], 60.0)
        finally:
            coord.evaluator.close()
            coord.destroy_node()
    finally:
        la.stop()
    assert node.restarts == 0


def test_the_coordinator_node_section_sets_the_coordinators_parameters(ros_domain, tmp_path):
    """The coordinator reads its parameters under its own node name: a config named only in the
    ``coordinator_node:`` section is the one it loads (here a missing file, so it stops at once
    and says which file it was given)."""
    import subprocess

    missing = tmp_path / "named_in_coordinator_section.yaml"
    params = tmp_path / "params.yaml"
    params.write_text(yaml.safe_dump({"coordinator_node": {"ros__parameters": {"config": str(missing)}}}))
    p = subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", "coordinator_node", "--ros-args",
                        "--params-file", str(params)], env=ros_env(ros_domain), capture_output=True, text=True,
                       timeout=120)
    assert p.returncode == 2, p.stderr
    assert f"{missing}: no such config file" in p.stderr


def _coordinator(ros_domain, *ros_args, cwd=REPO, timeout=120):
    import subprocess

    return subprocess.run([sys.executable, "-m", "bev_mdo.ros.run", "coordinator_node", "--ros-args", *ros_args],
                          env=ros_env(ros_domain), capture_output=True, text=True, timeout=timeout, cwd=cwd)


def _said_once(p, *words):
    """Exit 2 with one error line (after the node's 'starting' line), naming `words`, no traceback."""
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and "Traceback" not in p.stderr, p.stderr[-3000:]
    assert len(lines) <= 2 and all(w in lines[-1] for w in words), lines


def test_a_p_after_the_shipped_file_overrides_it(ros_domain):
    """docs/ros2-run.md: "A -p given after the file overrides it". The shipped file's coordinator section
    used to come after its /** section, and rclpy applies sections in that order (a -p joins /**)."""
    import rclpy
    from rclpy.node import Node

    def params(*args):
        ctx = rclpy.context.Context()
        rclpy.init(args=["x", "--ros-args", *args], context=ctx)
        try:
            node = Node("coordinator_node", context=ctx)
            got = {k: node.declare_parameter(k, d).value for k, d in
                   (("optimizer", ""), ("formulation", ""), ("recorders", 0), ("run_id", ""), ("config", ""))}
            node.destroy_node()
            return got
        finally:
            rclpy.shutdown(context=ctx)

    shipped = params("--params-file", str(SHIPPED))
    assert shipped == {"optimizer": "SLSQP", "formulation": "mdf", "recorders": 1, "run_id": "by_hand",
                       "config": "config/leaf_nedc.yaml"}
    later = params("--params-file", str(SHIPPED), "-p", "optimizer:=COBYLA", "-p", "formulation:=idf",
                   "-p", "recorders:=0", "-p", "run_id:=mine", "-p", "config:=other.yaml")
    assert later == {"optimizer": "COBYLA", "formulation": "idf", "recorders": 0, "run_id": "mine",
                     "config": "other.yaml"}
    # the coordinator itself runs with the later -p: an optimiser it does not know is refused at once
    p = _coordinator(ros_domain, "--params-file", str(SHIPPED), "-p", "optimizer:=NOSUCH")
    _said_once(p, "optimizer 'NOSUCH' is unknown")


@pytest.mark.parametrize("param, words", [("formulation:=xdf", ["formulation 'xdf' is unknown", "mdf, idf"]),
                                          ("optimizer:=FOO", ["optimizer 'FOO' is unknown", "SLSQP"]),
                                          ("recorders:=2", ["recorders must be 0 or 1"])])
def test_a_bad_static_parameter_is_refused_before_the_discovery_wait(ros_domain, tmp_path, param, words):
    """They were checked after the wait for the disciplines (exit 6 after ros.discovery_wait_s)."""
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain, "discovery_wait_s": 600.0}
    cfg = tmp_path / "slow.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    _said_once(_coordinator(ros_domain, "-p", f"config:={cfg}", "-p", param, timeout=300), *words)


@pytest.mark.parametrize("text, words", [
    ("recorders: one", ["parameter recorders: 'one' is STRING, expected INTEGER"]),
    ("config: 42", ["parameter config: 42 is INTEGER, expected STRING", "quote it"]),
    ("optimizer: [1, 2]", ["parameter optimizer: [1, 2] is INTEGER_ARRAY, expected STRING"])])
def test_a_parameter_of_the_wrong_type_is_one_line_exit_2(ros_domain, tmp_path, text, words):
    """rclpy's InvalidParameterTypeException stopped the coordinator with a 26-line traceback, exit 1."""
    params = tmp_path / "params.yaml"
    params.write_text(f"coordinator_node:\n  ros__parameters:\n    {text}\n")
    _said_once(_coordinator(ros_domain, "--params-file", str(params), cwd=tmp_path), *words)


@pytest.mark.parametrize("text, words", [
    (b"\xe2\x00garbage\x07", ["--params-file", "not a YAML text file"]),
    (b"/**:\n  ros__parameters:\n    config: a.yaml\n    config: b.yaml\n", ["duplicate key 'config'"]),
    (b"a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9]\n" + b"".join(b"%c: &%c [*%c, *%c, *%c, *%c, *%c, *%c, *%c, *%c, *%c]\n"
                                                     % ((98 + i,) * 2 + (97 + i,) * 9) for i in range(8)),
     ["an alias bomb?"])])
def test_a_malformed_parameters_file_is_one_line_exit_2(ros_domain, tmp_path, text, words):
    """A malformed-files trial: rcl's "Couldn't parse params file" came as a traceback, exit 1; a key given twice
    served the second value with no word."""
    params = tmp_path / "params.yaml"
    params.write_bytes(text)
    _said_once(_coordinator(ros_domain, "--params-file", str(params), cwd=tmp_path), *words)
