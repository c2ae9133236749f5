"""The Python API over ROS goes through the same core as the CLI: Study.evaluate and Study.sweep
through running discipline nodes, and Study.optimize with nodes it starts itself, give what the
in-process transport gives."""
from __future__ import annotations

import pytest

from bev_mdo import Study, Transport


def test_evaluate_and_sweep_over_ros_equal_in_process(leaf_nodes, leaf_config):
    study = Study(leaf_config)
    design = {"motor_kw": 90, "gear_ratio": 8.5, "battery_kwh": 30}
    running = Transport(attach=True)  # the leaf_nodes already running on the config's domain
    ros, local = study.evaluate(design, transport=running), study.evaluate(design, transport="inprocess")
    assert ros.ok and ros.outputs == pytest.approx(local.outputs, rel=1e-12)
    grid = {"motor_kw": [40, 80, 120], "gear_ratio": [7, 8, 9]}
    assert (study.sweep(designs=grid, transport=running).rows()
            == study.sweep(designs=grid, transport="inprocess").rows())


def test_optimize_over_ros_equals_in_process(ros_domain, leaf_config, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the run's logs and keys stay in the test's folder
    study = Study(leaf_config).constrain("range_km", lower=250)
    ros = study.optimize(transport=Transport(domain_id=ros_domain), no_record=True)  # the default: its own nodes
    local = study.optimize(transport="inprocess")
    assert ros.data["transport"] == "ros" and ros.verdict == local.verdict == "optimum"
    assert ros.x == pytest.approx(local.x, rel=1e-9, abs=1e-9)
    assert ros.objective == pytest.approx(local.objective, rel=1e-9)
