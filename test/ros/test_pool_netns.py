"""A pool across "machines": instances of one discipline in two network namespaces, the
coordinator in a third.

The test makes three namespaces joined by a bridge that lives in the coordinator's namespace,
with addresses 10.201.0.1 and 10.201.0.2 (discipline namespaces) and 10.201.0.3 (coordinator)
that exist only inside them, and removes all three afterwards (also on failure). Nothing has a
route out, so no packet can reach another network. Discovery: static peers (the coordinator
lists both discipline namespaces, each of them the coordinator and the other one: data flow
passes results from node to node). Skipped where namespaces
cannot be made (see test_netns.py).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import yaml


from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.launcher import Launcher  # noqa: E402
from bev_mdo.processes import discipline_argv  # noqa: E402
from bev_mdo.ros_settings import ros_environment, validate_ros  # noqa: E402
from bev_mdo.testing import REPO  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from test_netns import _ip, netns_unavailable  # noqa: E402

BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
DOMAIN = 74
A1, A2, AC = "10.201.0.1", "10.201.0.2", "10.201.0.3"


class Netns3:
    """Namespaces d1, d2 and c; a bridge in c with one veth to each of d1 and d2."""

    def __init__(self):
        tag = str(os.getpid() % 100000)
        self.d1, self.d2, self.c = f"bevpool_{tag}_1", f"bevpool_{tag}_2", f"bevpool_{tag}_c"
        self.tag = tag
        self.made: list[str] = []

    @staticmethod
    def _check(cp):
        if cp.returncode != 0:
            raise RuntimeError(f"{' '.join(cp.args)}: {cp.stderr.strip() or cp.stdout.strip()}")

    def create(self) -> None:
        for ns in (self.d1, self.d2, self.c):
            self._check(_ip("netns", "add", ns))
            self.made.append(ns)
        c = self.c
        self._check(_ip("-n", c, "link", "add", "br0", "type", "bridge"))
        for k, (ns, addr) in enumerate(((self.d1, A1), (self.d2, A2)), start=1):
            inner, outer = f"bp{self.tag}i{k}", f"bp{self.tag}o{k}"
            # the pair is made inside c, so no end of it ever exists in the host's namespace
            self._check(_ip("-n", c, "link", "add", inner, "type", "veth", "peer", "name", outer))
            self._check(_ip("-n", c, "link", "set", inner, "netns", ns))
            self._check(_ip("-n", c, "link", "set", outer, "master", "br0"))
            self._check(_ip("-n", c, "link", "set", outer, "up"))
            self._check(_ip("-n", ns, "addr", "add", f"{addr}/24", "dev", inner))
            self._check(_ip("-n", ns, "link", "set", inner, "up"))
            self._check(_ip("-n", ns, "link", "set", "lo", "up"))
        self._check(_ip("-n", c, "addr", "add", f"{AC}/24", "dev", "br0"))
        self._check(_ip("-n", c, "link", "set", "br0", "up"))
        self._check(_ip("-n", c, "link", "set", "lo", "up"))
        for ns in (self.d1, self.d2):  # the link is usable (no sleeping on a guess)
            self._check(subprocess.run(["ip", "netns", "exec", ns, "python3", "-c",
                                        "import socket,sys;s=socket.socket(socket.AF_INET,socket.SOCK_DGRAM);"
                                        f"s.connect(('{AC}',9));sys.exit(0)"],
                                       capture_output=True, text=True, timeout=30))

    def close(self) -> None:
        for ns in reversed(self.made):
            _ip("netns", "del", ns)
        self.made.clear()


@pytest.fixture(scope="module")
def netns3():
    why = netns_unavailable()
    if why:
        pytest.skip(why)
    nets = Netns3()
    try:
        nets.create()
        yield nets
    finally:
        nets.close()
        assert not {nets.d1, nets.d2, nets.c} & set(_ip("netns", "list").stdout.split())


def ns_env(peers: list[str]) -> dict[str, str]:
    ros = validate_ros({"domain_id": DOMAIN, "discovery": "static_peers", "static_peers": peers})
    env = ros_environment(ros)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"
    return env


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": DOMAIN, "discovery": "static_peers", "static_peers": [A1, A2],
                  "timeout_s": 5.0, "retries": 3, "discovery_wait_s": 90.0, "signing": False}
    p = tmp_path_factory.mktemp("cfg") / "pool_netns.yaml"
    p.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(p)


@pytest.fixture(scope="module")
def nodes(netns3, config_path, tmp_path_factory):
    # Data flow passes results from node to node (a pooled energy share in d2 reads vehicle_mass's
    # result from d1), so each discipline host lists the coordinator AND the other discipline host.
    la = Launcher(ns_env([AC, A2]), log_dir=tmp_path_factory.mktemp("logs"))
    la2 = Launcher(ns_env([AC, A1]), log_dir=tmp_path_factory.mktemp("logs2"))
    try:
        for name in BUILTINS:  # the whole suite in d1, a second energy instance in d2
            la.add(name, ["ip", "netns", "exec", netns3.d1, *discipline_argv(name, config_path)])
        la2.add("energy#2", ["ip", "netns", "exec", netns3.d2,
                             *discipline_argv("energy", config_path, instance="remote2")])
        yield la
    finally:
        la.stop()
        la2.stop()


def test_energy_pool_across_two_namespaces(netns3, nodes, config_path):
    config = load_config(config_path)
    ref = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    cp = subprocess.run(["ip", "netns", "exec", netns3.c, sys.executable, "-m", "bev_mdo.ros.run", "coordinator_node",
                         "--ros-args", "-p", f"config:={config_path}", "-p", "run_id:=pool-netns",
                         "-p", "instances:=energy=2"],
                        env=ns_env([A1, A2]), capture_output=True, text=True, timeout=300)
    assert cp.returncode == 0, cp.stderr[-3000:]
    lines = cp.stdout.splitlines()
    report = json.loads("\n".join(lines[max(i for i, line in enumerate(lines) if line == "{"):]))
    res = report["result"]
    assert res["objective"] == ref.objective and res["design"] == ref.design
    energy = report["pools"]["energy"]
    assert sorted(energy) == ["energy_node", "energy_node_remote2"], energy
    assert all(s["points"] > 0 and s["failures"] == 0 for s in energy.values()), energy
    assert all(n.restarts == 0 for n in nodes.nodes)
