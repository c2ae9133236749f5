"""Fixtures shared by the ROS tests: the Leaf NEDC config on the module's own domain, and its built-in
discipline nodes running as separate processes."""
from __future__ import annotations

import pytest
import yaml

from bev_mdo.launcher import Launcher
from bev_mdo.processes import discipline_argv
from bev_mdo.testing import REPO, ros_env

LEAF_DISCIPLINES = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]


@pytest.fixture(scope="module")
def leaf_config(ros_domain, tmp_path_factory):
    """config/leaf_nedc.yaml on the module's domain, with a long discovery wait (a loaded host)."""
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": ros_domain, "discovery_wait_s": 60.0}
    path = tmp_path_factory.mktemp("cfg") / "leaf.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def leaf_nodes(ros_domain, leaf_config, tmp_path_factory):
    """The Leaf's discipline nodes, one process each, stopped after the module."""
    launcher = Launcher(ros_env(ros_domain), log_dir=tmp_path_factory.mktemp("logs"))
    for name in LEAF_DISCIPLINES:
        launcher.add(name, discipline_argv(name, str(leaf_config)))
    yield launcher
    launcher.stop()
