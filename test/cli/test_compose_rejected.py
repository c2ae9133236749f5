"""A run whose --compose is rejected stops before it writes anything: no logs, no key, no bag."""
from __future__ import annotations

import subprocess
import sys

import pytest

from bev_mdo.testing import REPO, ros_env


@pytest.mark.parametrize("compose", ["energy+warp_drive", "energy+range,range+cost"])
def test_a_rejected_compose_leaves_nothing_behind(tmp_path, compose):
    env = {**ros_env(66), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    bag = tmp_path / "bags" / "run"
    p = subprocess.run([sys.executable, "-m", "bev_mdo", "optimize", str(REPO / "config" / "leaf_nedc.yaml"),
                        "--compose", compose, "--bag", str(bag), "--domain-id", "66"],
                       capture_output=True, text=True, cwd=tmp_path, timeout=120, env=env)
    assert p.returncode == 2 and "--compose" in p.stderr and "Traceback" not in p.stderr, p.stderr
    assert [q.relative_to(tmp_path) for q in tmp_path.rglob("*")] == [], "logs or a key were written"
