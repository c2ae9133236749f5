"""A node says it is starting before the slow imports (issue 17: nodes were silent for 2-3 s)."""
from __future__ import annotations

import subprocess
import sys

import pytest

from bev_mdo.testing import REPO, ros_env

pytestmark = pytest.mark.ros


def test_a_node_announces_itself_before_loading_ros(ros_domain):
    p = subprocess.Popen([sys.executable, "-m", "bev_mdo.ros.run", "cost_node", "--ros-args", "-p",
                          f"config:={REPO / 'config' / 'leaf_nedc.yaml'}"],
                         env=ros_env(ros_domain), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        first = p.stderr.readline()
    finally:
        p.terminate()
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    assert first.startswith("cost_node: starting"), first
