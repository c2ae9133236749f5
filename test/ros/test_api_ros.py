"""The Python API over ROS goes through the same core as the CLI: Study.evaluate and Study.sweep
through running discipline nodes, and Study.optimize with nodes it starts itself, give what the
in-process transport gives."""
from __future__ import annotations

import pytest
import yaml

from bev_mdo import Study, Transport
from bev_mdo.ros.launch import Launcher, discipline_argv
from bev_mdo.testing import REPO, ros_env

BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


@pytest.fixture(scope="module")
def config(ros_domain, tmp_path_factory):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain, "discovery_wait_s": 60.0}
    path = tmp_path_factory.mktemp("cfg") / "leaf.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def nodes(ros_domain, config, tmp_path_factory):
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for name in BUILTINS:
        launcher.add(name, discipline_argv(name, str(config)))
    yield launcher
    launcher.stop()


def test_evaluate_and_sweep_over_ros_equal_in_process(nodes, config):
    study = Study(config)
    design = {"motor_kw": 90, "gear_ratio": 8.5, "battery_kwh": 30}
    ros, local = study.evaluate(design, transport="ros"), study.evaluate(design)
    assert ros.ok and ros.outputs == pytest.approx(local.outputs, rel=1e-12)
    grid = {"motor_kw": [40, 80, 120], "gear_ratio": [7, 8, 9]}
    assert study.sweep(designs=grid, transport=Transport(transport="ros")).rows() == study.sweep(designs=grid).rows()


def test_optimize_over_ros_equals_in_process(ros_domain, config, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the run's logs and keys stay in the test's folder
    study = Study(config).constrain("range_km", lower=250)
    ros = study.optimize(transport=Transport(transport="ros", domain_id=ros_domain), no_record=True)
    local = study.optimize()
    assert ros.data["transport"] == "ros" and ros.verdict == local.verdict == "optimum"
    assert ros.x == pytest.approx(local.x, rel=1e-9, abs=1e-9)
    assert ros.objective == pytest.approx(local.objective, rel=1e-9)
