"""Where designs are evaluated: in this process, or through the discipline nodes of a ROS domain.

``Transport`` holds the choice and the ROS discovery settings (the ``--transport``, ``--attach``,
``--domain-id``, ``--discovery``... flags of every CLI command that evaluates designs carry the same
names, bev_mdo.cli.flags). Its one default, for every command and every ``Study`` run, is ``ros`` with
the command's own discipline nodes: started for the call on its domain, bound to it by a fresh run id
and signed with a per-run key, stopped after. ``attach`` uses the nodes already running on the domain
instead (``ros2 run``, ``bev-mdo node``); ``inprocess`` runs the same disciplines with no ROS.

The domain follows the ROS convention (settings.choose_domain): ``domain_id``, else the config's
``ros.domain_id`` when it states one, else ``ROS_DOMAIN_ID`` of the environment, else 77; when the
config overrides the environment, one line on stderr says so.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, fields
from typing import Any, Mapping

from bev_mdo.api.errors import InputError


TRANSPORTS = ("ros", "inprocess")
DEFAULT_TRANSPORT = "ros"


@dataclass
class Transport:
    transport: str = DEFAULT_TRANSPORT  # "ros" or "inprocess"
    attach: bool = False  # ros: the nodes already running on the domain, not the call's own
    domain_id: int | None = None
    discovery: str | None = None  # localhost (default), static_peers, server, subnet
    static_peers: str | None = None  # "IP[,IP...]"
    discovery_server: str | None = None  # "IP:PORT"

    def __post_init__(self):
        """A domain id that is no ROS domain (300, "x") is refused here, not at the run (in process, any
        domain id given is refused as a whole: refuse_ros_only)."""
        if self.domain_id is not None and self.transport != "inprocess":
            import numpy as np

            from bev_mdo.ros_settings import check_domain_id

            if isinstance(self.domain_id, np.integer):  # as the API's counts and seeds (models.common.check_whole)
                self.domain_id = int(self.domain_id)
            try:
                check_domain_id(self.domain_id, "domain_id")
            except ValueError as exc:
                raise InputError(str(exc)) from None

    @classmethod
    def of(cls, obj) -> "Transport":
        """The transport settings of a parsed command line (or any object with these attributes)."""
        if isinstance(obj, str):
            return cls(transport=obj)
        return cls(**{f.name: getattr(obj, f.name) for f in fields(cls) if hasattr(obj, f.name)})

    @property
    def uses_ros(self) -> bool:
        if self.transport not in TRANSPORTS:
            raise InputError(f"transport {self.transport!r}: allowed: {', '.join(TRANSPORTS)}")
        if self.attach and self.transport != "ros":
            raise InputError("--attach uses the discipline nodes running on the ROS domain: "
                             "it cannot be combined with --transport inprocess")
        return self.transport == "ros"

    def refuse_ros_only(self, own: tuple = ()) -> None:
        """InputError naming the ROS-only flags given to an in-process run (they would be ignored silently):
        the discovery flags and the command's ``own`` (flag, value) pairs; None is not given."""
        if self.uses_ros:
            return
        given = [flag for flag, value in (*own, ("--domain-id", self.domain_id), ("--discovery", self.discovery),
                                          ("--static-peers", self.static_peers),
                                          ("--discovery-server", self.discovery_server)) if value is not None]
        if given:
            raise InputError(f"{', '.join(given)} cannot be combined with --transport inprocess (it starts no ROS nodes)")

    def refuse_attach(self, command: str) -> None:
        """InputError for a command that must start its own nodes (a run bound to its recorder and key)."""
        if self.uses_ros and self.attach:
            raise InputError(attach_refused(command))


def attach_refused(command: str) -> str:
    """The line refusing ``--attach`` to a command that starts its own nodes (optimize, resume, pareto)."""
    return (f"{command} --attach: {command} runs its own discipline nodes, bound to its run and recorder (drop "
            "--attach); --attach is for evaluate, sweep, compare, sensitivity and check-totals (an optimisation "
            "over nodes you started: ros2 run bev_mdo coordinator_node, docs/ros2-run.md)")


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
    for flag, mode in (("static_peers", "static_peers"), ("discovery_server", "server")):
        if getattr(args, flag, None) and ros.get("discovery") != mode:  # it was ignored without a word
            raise InputError(f"--{flag.replace('_', '-')} goes with --discovery {mode} "
                             f"(discovery is {ros.get('discovery', 'localhost')!r})")
    return validate_ros(ros)


class Evaluating:
    """``with Evaluating(config, transport) as ev:`` the evaluator of ``config`` on the transport: in
    process, or over ROS (``evaluate``, ``sweep``, ``sensitivity``, ``check-totals``) the nodes already
    running on the domain (``attach``) or the command's own (launcher.OwnSuite: a fresh run id, signed
    with a per-run key by default), stopped at the end. A ROS evaluator's notes for the user (what was
    dropped; results that were not signed, which anyone on the domain could have answered) are printed
    on stderr only when the block ended normally."""

    def __init__(self, config, transport, node_name: str = "bev_mdo_client", announce: bool = False):
        from bev_mdo.config import RunConfig

        how = Transport.of(transport)  # ros_section gets ``transport`` itself: its domain note shows once per command
        self.ros, self.suite = how.uses_ros, None
        if not self.ros:
            how.refuse_ros_only()  # --domain-id, --discovery, ... would be ignored in process
            from bev_mdo.mdo.evaluator import InProcessEvaluator

            self.evaluator = InProcessEvaluator(RunConfig.of(config).timed_disciplines())
            return
        if announce:
            section = ros_section(config, transport)
            what = "find the discipline nodes" if how.attach else "start the discipline nodes"
            print(f"waiting up to {section['discovery_wait_s']:g} s to {what} on ROS domain "
                  f"{section['domain_id']} ...", file=sys.stderr, flush=True)
        import importlib

        try:  # the ROS libraries only: a bev_mdo module that fails to import raises as it is
            for lib in ("rclpy", "bev_mdo_msgs.msg"):
                importlib.import_module(lib)
        except ModuleNotFoundError:
            raise InputError("--transport ros needs the ROS transport (rclpy and bev_mdo_msgs); "
                             "--transport inprocess runs without it") from None
        from bev_mdo.ros.client import make_ros_evaluator

        section = ros_section(config, transport)
        self.domain, run_id = section["domain_id"], None
        if how.attach:
            config = RunConfig.of(config).with_ros(section)
        else:
            from bev_mdo.launcher import OwnSuite

            self.suite = OwnSuite(config, section).start()
            config, run_id = self.suite.config, self.suite.run_id
        try:
            self.evaluator = make_ros_evaluator(config, node_name=node_name, run_id=run_id)
            if self.suite is not None:  # retries wait for a node the suite's launcher is restarting
                self.evaluator.inner.recovering = self.suite.launcher.recovering
        except BaseException:
            if self.suite is not None:
                self.suite.stop()
            raise

    def __enter__(self):
        return self.evaluator

    def __exit__(self, exc_type, *exc):
        try:
            self.evaluator.close()
        finally:
            if self.suite is not None:
                self.suite.stop()
        if exc_type is not None or not self.ros:
            return
        dropped = {k: v for k, v in self.evaluator.dropped.items() if v}
        if dropped:
            print("bev-mdo: dropped and counted: " + ", ".join(f"{k} {v}" for k, v in sorted(dropped.items())),
                  file=sys.stderr)
        if not self.evaluator.signed:
            print("bev-mdo: note: the results were not signed " + (
                "(ros.signing: false)" if self.suite is not None else
                f"(no ros.sign_key_file): any process on ROS domain {self.domain} could have answered; "
                "run without --attach, or use a key file (docs/security.md)"), file=sys.stderr)
