"""Command-line flags for joining a ROS graph; they override the config's `ros:` section.

The domain follows the ROS convention (settings.choose_domain): ``--domain-id``, else the
config's ``ros.domain_id`` when it states one, else ``ROS_DOMAIN_ID`` of the environment, else 77.
When the config overrides the environment, one line on stderr says so.
"""
from __future__ import annotations

import argparse
from typing import Any, Mapping


def add_ros_arguments(parser) -> None:
    """The discovery flags shared by commands that join a ROS graph (they override the config's ros: section)."""
    g = parser.add_argument_group("ROS discovery (default: the config's ros: section; localhost only)")
    g.add_argument("--domain-id", type=int, default=None,
                   help="ROS domain id (default: the config's ros.domain_id if it sets one, else ROS_DOMAIN_ID, else 77)")
    g.add_argument("--discovery", choices=["localhost", "static_peers", "server", "subnet"], default=None,
                   help="how nodes find each other; anything but localhost is an explicit opt-in to other hosts")
    g.add_argument("--static-peers", default=None, metavar="IP[,IP...]", help="with --discovery static_peers")
    g.add_argument("--discovery-server", default=None, metavar="IP:PORT", help="with --discovery server")


def ros_section(config: Mapping[str, Any], args) -> dict:
    """The validated ros: section of `config` with the command-line flags and the domain rule applied."""
    from bev_mdo.ros_settings import validate_ros

    import sys

    from bev_mdo.ros_settings import choose_domain

    ros = dict(config.get("ros") or {})
    ros["domain_id"], note = choose_domain(ros, getattr(args, "domain_id", None))
    if note and not getattr(args, "_domain_note_shown", False):
        print(f"bev-mdo: {note}", file=sys.stderr)
        try:
            args._domain_note_shown = True  # one line per command, however often the section is built
        except AttributeError:
            pass
    if getattr(args, "discovery", None):
        ros["discovery"] = args.discovery
    if getattr(args, "static_peers", None):
        ros["static_peers"] = [p.strip() for p in args.static_peers.split(",") if p.strip()]
    if getattr(args, "discovery_server", None):
        ros["discovery_server"] = args.discovery_server
    return validate_ros(ros)


def add_transport_arguments(parser) -> None:
    """The transport flags of a command that evaluates designs without starting its own run of nodes
    (evaluate, sweep, compare, sensitivity, check-totals), with the discovery flags."""
    g = parser.add_argument_group("transport")
    g.add_argument("--transport", choices=["inprocess", "ros"], default="inprocess",
                   help="inprocess (default): no ROS; ros: through the discipline nodes running on the domain")
    g.add_argument("--launch", action="store_true",
                   help="start the config's discipline nodes for this command and stop them after (implies "
                        "--transport ros): bound to this command and signed with a fresh per-run key, as optimize does")
    g.add_argument("--ros", action="store_true", help=argparse.SUPPRESS)  # the old spelling of --transport ros
    add_ros_arguments(parser)


def uses_ros(args) -> bool:
    """True when the command's designs go over ROS (``--transport ros``, ``--launch`` or the old ``--ros``)."""
    return getattr(args, "transport", "inprocess") == "ros" or bool(getattr(args, "launch", False)) \
        or bool(getattr(args, "ros", False))
