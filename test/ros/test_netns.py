"""Remote coordination across network namespaces (two "hosts" on one machine).

The test creates two network namespaces joined by a veth pair, with addresses
10.200.1.1/24 (disciplines) and 10.200.1.2/24 (coordinator) that exist only inside
them, and removes both afterwards (also on failure). The namespaces have no other
interface and no route, so no packet can reach any other network. Discovery is by
static peers (ROS_STATIC_PEERS, localhost range), as configured by the `ros:` section
`discovery: static_peers`. Skipped, with the reason, where namespaces cannot be made.
"""
from __future__ import annotations

import json
import os
import shutil
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

BUILTINS = ["vehicle_mass", "energy", "range", "acceleration", "motor_speed", "cost"]
DOMAIN = 85
ADDR_DISC, ADDR_COORD = "10.200.1.1", "10.200.1.2"


def _ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)


class NetnsPair:
    """Two namespaces and a veth between them; `close()` deletes everything it made."""

    def __init__(self, tag: str):
        self.a, self.b = f"bevmdo_{tag}_d", f"bevmdo_{tag}_c"
        self.made: list[str] = []

    def create(self) -> None:
        va, vb = f"bv{os.getpid() % 100000}a", f"bv{os.getpid() % 100000}b"
        for ns in (self.a, self.b):
            self._check(_ip("netns", "add", ns))
            self.made.append(ns)
        self._check(_ip("link", "add", va, "type", "veth", "peer", "name", vb))
        self._check(_ip("link", "set", va, "netns", self.a))
        self._check(_ip("link", "set", vb, "netns", self.b))
        for ns, dev, addr in ((self.a, va, ADDR_DISC), (self.b, vb, ADDR_COORD)):
            self._check(_ip("-n", ns, "addr", "add", f"{addr}/24", "dev", dev))
            self._check(_ip("-n", ns, "link", "set", "lo", "up"))
            self._check(_ip("-n", ns, "link", "set", dev, "up"))
        # wait until the link is usable (no sleeping on a guess): one ping inside the pair
        self._check(subprocess.run(["ip", "netns", "exec", self.a, "ping", "-c", "1", "-W", "5", ADDR_COORD],
                                   capture_output=True, text=True, timeout=30)
                    if shutil.which("ping") else _ip("-n", self.a, "link", "show", va))

    @staticmethod
    def _check(cp: subprocess.CompletedProcess) -> None:
        if cp.returncode != 0:
            raise RuntimeError(f"{' '.join(cp.args)}: {cp.stderr.strip() or cp.stdout.strip()}")

    def close(self) -> None:
        for ns in reversed(self.made):  # deleting a namespace deletes its end of the veth, and so both
            _ip("netns", "del", ns)
        self.made.clear()


def netns_unavailable() -> str | None:
    """Why namespaces cannot be used here, or None."""
    if shutil.which("ip") is None:
        return "the `ip` tool is not installed"
    if os.geteuid() != 0:
        return "creating network namespaces needs root (CAP_SYS_ADMIN)"
    probe = f"bevmdo_probe_{os.getpid()}"
    cp = _ip("netns", "add", probe)
    if cp.returncode != 0:
        return f"`ip netns add` is not permitted here: {cp.stderr.strip()}"
    _ip("netns", "del", probe)
    return None


@pytest.fixture(scope="module")
def netns():
    why = netns_unavailable()
    if why:
        pytest.skip(why)
    pair = NetnsPair(str(os.getpid() % 100000))
    try:
        pair.create()
        yield pair
    finally:
        pair.close()
        assert not {pair.a, pair.b} & set(_ip("netns", "list").stdout.split())


def ns_env(peer: str) -> dict[str, str]:
    """Environment of a process in one namespace: static peer = the other namespace's address."""
    ros = validate_ros({"domain_id": DOMAIN, "discovery": "static_peers", "static_peers": [peer]})
    env = ros_environment(ros)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_STATIC_PEERS"] == peer
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    env["PYTHONUNBUFFERED"] = "1"
    return env


@pytest.fixture(scope="module")
def config_path(tmp_path_factory):
    raw = yaml.safe_load((REPO / "config" / "leaf_nedc.yaml").read_text())
    raw["ros"] = {"domain_id": DOMAIN, "discovery": "static_peers", "static_peers": [ADDR_DISC],
                  "timeout_s": 5.0, "retries": 3, "discovery_wait_s": 60.0}
    p = tmp_path_factory.mktemp("cfg") / "netns.yaml"
    p.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(p)


@pytest.fixture(scope="module")
def remote_nodes(netns, config_path, tmp_path_factory):
    la = Launcher(ns_env(ADDR_COORD), log_dir=tmp_path_factory.mktemp("logs"))
    try:
        for name in BUILTINS:
            la.add(name, ["ip", "netns", "exec", netns.a, *discipline_argv(name, config_path)])
        la.supervise()
        yield la
    finally:
        la.stop()


def run_coordinator_in(ns: str, config_path: str, run_id: str, timeout_s: float = 300) -> dict:
    """`coordinator_node` in namespace `ns`; returns its JSON report."""
    cp = subprocess.run(["ip", "netns", "exec", ns, sys.executable, "-m", "bev_mdo.ros.run", "coordinator_node",
                         "--ros-args", "-p", f"config:={config_path}", "-p", f"run_id:={run_id}"],
                        env=ns_env(ADDR_DISC), capture_output=True, text=True, timeout=timeout_s)
    assert cp.returncode == 0, cp.stderr[-3000:]
    lines = cp.stdout.splitlines()
    start = max(i for i, line in enumerate(lines) if line == "{")
    return json.loads("\n".join(lines[start:]))


def test_coordinator_in_another_namespace_reaches_the_same_optimum(netns, remote_nodes, config_path):
    config = load_config(config_path)
    ref = run_optimization(config, InProcessEvaluator(resolve_disciplines(config)))
    report = run_coordinator_in(netns.b, config_path, "netns-run")
    res = report["result"]
    assert report["run_id"] == "netns-run"
    assert res["feasible"] == ref.feasible
    for k, v in ref.design.items():
        assert res["design"][k] == pytest.approx(v, rel=1e-12), k
    assert res["objective"] == pytest.approx(ref.objective, rel=1e-12)
    assert len(res["history"]) == len(ref.history)
    assert all(n.restarts == 0 for n in remote_nodes.nodes)

