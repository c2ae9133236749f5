"""Shared fixtures. Every test module that touches ROS gets its own domain id and
localhost-only discovery (network hygiene), set before rclpy initialises."""
from __future__ import annotations

import os

import pytest

from bev_mdo.testing import domain_for


@pytest.fixture(scope="module")
def ros_domain(request):
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
    yield domain
    for k, v in old.items():
        if v is None:
            os.environ.pop(k, None)
        else:
            os.environ[k] = v


@pytest.fixture(scope="module")
def rclpy_context(ros_domain):
    """An initialised rclpy context for this module (domain set first)."""
    rclpy = pytest.importorskip("rclpy")
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.shutdown(context=ctx)
