"""Where designs are evaluated: in this process, or through the discipline nodes of a ROS domain.

``Transport`` holds the choice and the ROS discovery settings (the ``--transport``, ``--launch``,
``--domain-id``, ``--discovery``... flags of the CLI carry the same names). The domain follows the
ROS convention (settings.choose_domain): ``domain_id``, else the config's ``ros.domain_id`` when it
states one, else ``ROS_DOMAIN_ID`` of the environment, else 77; when the config overrides the
environment, one line on stderr says so.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, fields
from typing import Any, Mapping

from bev_mdo.api.errors import InputError


@dataclass
class Transport:
    transport: str = "inprocess"  # or "ros"
    launch: bool = False  # start the config's discipline nodes for this call (implies ros)
    domain_id: int | None = None
    discovery: str | None = None  # localhost (default), static_peers, server, subnet
    static_peers: str | None = None  # "IP[,IP...]"
    discovery_server: str | None = None  # "IP:PORT"

    @classmethod
    def of(cls, obj) -> "Transport":
        """The transport settings of a parsed command line (or any object with these attributes)."""
        t = cls(**{f.name: getattr(obj, f.name) for f in fields(cls) if hasattr(obj, f.name)})
        if getattr(obj, "ros", False):  # the old spelling of --transport ros
            t.transport = "ros"
        return t

    @property
    def uses_ros(self) -> bool:
        if self.transport not in ("inprocess", "ros"):
            raise InputError(f"transport {self.transport!r}: allowed: inprocess, ros")
        return self.transport == "ros" or self.launch


def ros_section(config: Mapping[str, Any], args) -> dict:
    """The validated ros: section of `config` with the transport's settings and the domain rule applied."""
    from bev_mdo.ros_settings import choose_domain, validate_ros

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


def ros_session(config, transport, node_name: str = "bev_mdo_client"):
    """The ROS session (sessions.EvaluateRosSession) of evaluate/sensitivity/sweep over ROS;
    InputError when the ROS transport is not installed."""
    import importlib

    try:  # the ROS libraries only: a bev_mdo module that fails to import raises as it is
        for lib in ("rclpy", "bev_mdo_msgs.msg"):
            importlib.import_module(lib)
    except ModuleNotFoundError:
        raise InputError("--ros needs the ROS transport (rclpy and bev_mdo_msgs)") from None
    from bev_mdo.sessions import EvaluateRosSession

    return EvaluateRosSession(config, ros_section(config, transport), launch=bool(getattr(transport, "launch", False)),
                              node_name=node_name)


def close_ros(session, ok: bool = True) -> None:
    """End a ROS session; print its notes (drops, unsigned results) on stderr if the call ended well."""
    for line in session.close(ok):
        print(f"bev-mdo: {line}", file=sys.stderr)


class Evaluating:
    """``with Evaluating(config, transport) as ev:`` the evaluator of ``config`` on the transport
    (in process, or an EvaluateRosSession's), closed at the end (a ROS session's notes printed
    only when the block ended normally)."""

    def __init__(self, config, transport, node_name: str = "bev_mdo_client", announce: bool = False):
        self.ros = Transport.of(transport).uses_ros
        if self.ros:
            if announce:
                section = ros_section(config, transport)
                what = "start the discipline nodes" if getattr(transport, "launch", False) else "find the discipline nodes"
                print(f"waiting up to {section.get('discovery_wait_s', 20):g} s to {what} on ROS domain "
                      f"{section['domain_id']} ...", file=sys.stderr, flush=True)
            self.session = ros_session(config, transport, node_name)
        else:
            from bev_mdo.config import RunConfig
            from bev_mdo.mdo.evaluator import InProcessEvaluator

            self.session = InProcessEvaluator(RunConfig.of(config).disciplines)

    def __enter__(self):
        return self.session.evaluator if self.ros else self.session

    def __exit__(self, exc_type, *exc):
        if self.ros:
            close_ros(self.session, exc_type is None)
        else:
            self.session.close()
