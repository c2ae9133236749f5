"""A node says it is starting before the slow imports (they were silent for 2-3 s)."""
from __future__ import annotations

import subprocess
import sys

import pytest

from bev_mdo.testing import REPO, ros_env

pytestmark = pytest.mark.ros


def _stop(p: subprocess.Popen) -> None:
    p.terminate()
    try:
        p.wait(timeout=30)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()


def test_a_node_announces_itself_before_loading_ros(ros_domain):
    p = subprocess.Popen([sys.executable, "-m", "bev_mdo.ros.run", "cost_node", "--ros-args", "-p",
                          f"config:={REPO / 'config' / 'leaf_nedc.yaml'}"],
                         env=ros_env(ros_domain), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    try:
        first = p.stderr.readline()
    finally:
        _stop(p)
    assert first.startswith("cost_node: starting"), first


def test_a_node_bound_to_an_all_digit_run_id_serves_it(ros_domain):
    """A run id of hex digits that happen to be decimal ("12345678") reaches the node as a string
    (an unquoted -p run_id:=12345678 was parsed as an integer and the node died)."""
    from bev_mdo.processes import discipline_argv

    argv = discipline_argv("cost", str(REPO / "config" / "leaf_nedc.yaml"), run_id="12345678")
    p = subprocess.Popen(argv, env=ros_env(ros_domain), stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
    lines = []
    try:
        for line in p.stderr:  # ends when the node dies; the node says "serving ..." once it is up
            lines.append(line)
            if "serving 'cost'" in line or len(lines) > 50:
                break
    finally:
        _stop(p)
    assert any("bound to run 12345678" in line for line in lines), "".join(lines)[-2000:]
