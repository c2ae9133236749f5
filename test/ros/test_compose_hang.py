"""A user discipline that hangs, composed into the coordinator's process (``--compose coordinator``,
composed.Beside, the default layout): its call is bounded by ros.timeout_s x (ros.retries + 1) as in
process (mdo/timed.py), only it is named (with the point it hung at), the run ends with exit 4 as in
the other layouts, and a Ctrl-C during the hang still interrupts the run."""
from __future__ import annotations

import json
import signal
import subprocess

import pytest
import yaml

from bev_mdo.testing import PYTHON, REPO, ros_env, wait_until

ROS_DOMAIN = 197

HANGS = '''
import pathlib, time
import numpy as np


class HangAbove:
    """Hangs for any motor above 84 kW (COBYLA's first step from 80 kW goes to 88 kW)."""
    name = "hang"
    inputs = ("motor_kw", "gear_ratio")
    outputs = ("hang_penalty",)
    units = {"motor_kw": "kW", "gear_ratio": "1", "hang_penalty": "1"}

    def compute(self, inputs):
        if np.any(inputs["motor_kw"] > 84):
            pathlib.Path("hanging").touch()  # the test's event: the hang has begun
            time.sleep(3600)
        return {"hang_penalty": 0.001 * inputs["motor_kw"] * inputs["gear_ratio"]}
'''


def _start(tmp_path, ros: dict, *argv: str) -> subprocess.Popen:
    (tmp_path / "hangs.py").write_text(HANGS)
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["disciplines"] = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost",
                          {"name": "hang", "class": "hangs:HangAbove"}]
    raw["problem"]["constraints"]["hang_penalty"] = {"upper": 100.0}
    raw["optimizer"] = {"name": "COBYLA", "options": {}}
    raw["ros"] = {**ros, "domain_id": ROS_DOMAIN, "discovery_wait_s": 60.0}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    env = ros_env(ROS_DOMAIN)
    env["PYTHONPATH"] = f"{tmp_path}:{env['PYTHONPATH']}"
    return subprocess.Popen([PYTHON, "-m", "bev_mdo", "optimize", "c.yaml", "--json", "--quiet", *argv],
                            env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


@pytest.mark.parametrize("record", [False, True], ids=["direct", "recorded"])
def test_a_hung_discipline_composed_beside_the_coordinator_is_bounded_named_and_exits_4(tmp_path, record):
    """Direct calls (nobody else listens) and published ones (the recorder listens) alike: it froze the
    run for the whole hang, then blamed all seven disciplines, each attempt of the retry hanging again."""
    p = _start(tmp_path, {"timeout_s": 2.0, "retries": 1}, *(["--bag", "bag"] if record else ["--no-record"]))
    try:
        out, err = p.communicate(timeout=240)
    finally:
        p.kill()
    assert p.returncode == 4, err[-3000:]
    doc = json.loads(out)
    assert doc["unresponsive_disciplines"] == ["hang"], doc
    named = doc["discipline_errors"]
    assert list(named) == ["hang"] and "no answer within 4 s" in named["hang"], named
    assert "at point 0 (motor_kw=" in named["hang"], named  # the point it hung at
    assert "discipline 'hang' did not answer within 2 x 2 s" in err, err[-3000:]
    assert "no answer from [" not in err, err[-3000:]  # no retry blaming the disciplines that answered
    assert doc["verdict"] != "optimum" and doc["design"]["motor_kw"] <= 84, doc["design"]


def test_a_ctrl_c_during_the_hang_interrupts_the_run(tmp_path):
    p = _start(tmp_path, {"timeout_s": 300.0, "retries": 0}, "--no-record")
    try:
        assert wait_until(lambda: (tmp_path / "hanging").exists() or p.poll() is not None, 120.0), "no hang"
        assert p.poll() is None, p.communicate()[1][-3000:]
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
    finally:
        p.kill()
    assert p.returncode == 130, err[-3000:]
