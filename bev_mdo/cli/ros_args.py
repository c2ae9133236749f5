"""Command-line flags for joining a ROS graph; they override the config's `ros:` section."""
from __future__ import annotations

from typing import Any, Mapping


def add_ros_arguments(parser) -> None:
    """The discovery flags shared by commands that join a ROS graph (they override the config's ros: section)."""
    g = parser.add_argument_group("ROS discovery (default: the config's ros: section; localhost only)")
    g.add_argument("--domain-id", type=int, default=None, help="ROS domain id")
    g.add_argument("--discovery", choices=["localhost", "static_peers", "server", "subnet"], default=None,
                   help="how nodes find each other; anything but localhost is an explicit opt-in to other hosts")
    g.add_argument("--static-peers", default=None, metavar="IP[,IP...]", help="with --discovery static_peers")
    g.add_argument("--discovery-server", default=None, metavar="IP:PORT", help="with --discovery server")


def ros_section(config: Mapping[str, Any], args) -> dict:
    """The validated ros: section of `config` with the command-line flags applied."""
    from bev_mdo.ros.settings import validate_ros

    ros = dict(config.get("ros") or {})
    if getattr(args, "domain_id", None) is not None:
        ros["domain_id"] = args.domain_id
    if getattr(args, "discovery", None):
        ros["discovery"] = args.discovery
    if getattr(args, "static_peers", None):
        ros["static_peers"] = [p.strip() for p in args.static_peers.split(",") if p.strip()]
    if getattr(args, "discovery_server", None):
        ros["discovery_server"] = args.discovery_server
    return validate_ros(ros)
