"""Shared fixtures. Every test module that touches ROS gets its own domain id and
localhost-only discovery (network hygiene), set before rclpy initialises."""
from __future__ import annotations

import os
from pathlib import Path

import pytest

from bev_mdo.testing import domain_for

HERE = Path(__file__).resolve().parent
ROS_FIXTURES = {"ros_domain", "rclpy_context"}


def pytest_collection_modifyitems(config, items):
    """Mark every test that runs ROS 2 as ``ros`` (so ``-m "not ros"`` skips the ROS suite): all of
    test/ros, and any test elsewhere that takes a ROS domain or an rclpy context (the ROS CLI tests,
    the recorder and replay tests mark themselves)."""
    for item in items:
        path = Path(str(item.path)).resolve()
        if HERE / "ros" in path.parents or ROS_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.ros)


def clean_zombie_shm() -> None:
    """Remove Fast DDS shared-memory files whose owner died (bev_mdo.shm: only files whose lock no live
    process holds). The suite SIGKILLs nodes on purpose; a later participant on the same port (the same
    module's domain, in this run or the next one on the host) could otherwise hang at start on a zombie port
    (eProsima/Fast-DDS#1144, #2811)."""
    from bev_mdo.shm import remove_orphans

    remove_orphans()


@pytest.fixture(scope="module")
def ros_domain(request, tmp_path_factory):
    """Set this module's own ROS domain in os.environ (for in-process rclpy) and return it.

    A module may pin its domain with a module-level ``ROS_DOMAIN = N``; otherwise it is a
    stable hash of the module name (bev_mdo.testing.domain_for)."""
    domain = getattr(request.module, "ROS_DOMAIN", None) or domain_for(request.module.__name__)
    keys = ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS",
            "ROS_DISCOVERY_SERVER")
    old = {k: os.environ.get(k) for k in keys}
    for k in keys[2:]:
        os.environ.pop(k, None)
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    # this process's ROS log (and its children's, unless a run puts them in its own folder) stays out of ~/.ros/log
    os.environ.setdefault("ROS_LOG_DIR", str(tmp_path_factory.getbasetemp() / "ros_log"))
    clean_zombie_shm()
    yield domain
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


@pytest.fixture(scope="module")
def rclpy_context(ros_domain):
    """An initialised rclpy context for this module (domain set first)."""
    import rclpy
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.shutdown(context=ctx)
