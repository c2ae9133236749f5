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


@pytest.mark.parametrize("compose", ["energy+nosuch", ""])
def test_a_rejected_compose_says_nothing_before_its_error(tmp_path, monkeypatch, capsys, compose):
    """The "starting 6 discipline nodes ..." line used to print before the error; --compose "" ran as none."""
    from bev_mdo.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["optimize", str(REPO / "config" / "leaf_nedc.yaml"), "--compose", compose, "--domain-id", "66"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.strip().splitlines()) == 1 and "--compose" in err, (out, err)
    assert list(tmp_path.iterdir()) == []


def test_a_pooled_discipline_in_a_group_is_named_as_pooled(tmp_path, monkeypatch, capsys):
    """--instances energy=2 --compose energy+range said "no discipline 'energy' in the config"."""
    from bev_mdo.cli import main

    monkeypatch.chdir(tmp_path)
    assert main(["optimize", str(REPO / "config" / "leaf_nedc.yaml"), "--instances", "energy=2", "--compose",
                 "energy+range", "--domain-id", "66"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'energy' runs as a pool (--instances)" in err[0], err
