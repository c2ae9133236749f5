"""``bev-mdo status``: the live discipline instances on a ROS domain, with host and throughput."""
from __future__ import annotations

from bev_mdo import jsontext


def register(sub) -> None:
    from bev_mdo.cli.flags import add_ros_arguments

    p = sub.add_parser("status")
    p.add_argument("config", nargs="?", default=None, help="run config YAML whose ros: section to use (optional)")
    p.add_argument("--listen", type=float, default=2.0, metavar="S", help="seconds to listen (default 2)")
    p.add_argument("--json", action="store_true", help="print the rows as JSON")
    add_ros_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    import rclpy

    from bev_mdo.api.transport import ros_section
    from bev_mdo.ros.client import apply_ros_environment
    from bev_mdo.ros.status import collect

    if not 0 < args.listen <= 600:
        raise ValueError(f"--listen must be in (0, 600] seconds, got {args.listen:g}")
    config = {}
    if args.config:
        from bev_mdo.config import RunConfig

        config = RunConfig.load(args.config)
    ros = ros_section(config, args)
    apply_ros_environment(ros)
    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node("bev_mdo_status", context=ctx)
        rows = collect(node, args.listen)
        node.destroy_node()
    finally:
        rclpy.shutdown(context=ctx)
    if args.json:
        print(jsontext.dumps(rows))
    elif rows:
        print(format_table(rows))
        for line in shared_names(rows):
            print(line)
    else:
        print(f"no discipline instance on ROS domain {ros['domain_id']} (listened {args.listen:g} s)")
    return 0


def format_table(rows: list[dict]) -> str:
    """The status rows as an aligned text table (one line per instance)."""
    head = ("DISCIPLINE", "INSTANCE", "LIVE", "HOST", "PID", "RUN", "POINTS", "PTS/S(CPU)", "PTS/S(NOW)", "FINGERPRINT")
    lines = [head]
    for r in rows:
        lines.append((r["discipline"], r["instance"], "yes" if r["live"] else "no", str(r["host"]), str(r["pid"] or "?"),
                      r["run_id"][:16], str(r["points"]),
                      "-" if r["capacity_points_per_s"] is None else f"{r['capacity_points_per_s']:g}",
                      "-" if r["recent_points_per_s"] is None else f"{r['recent_points_per_s']:g}",
                      r["fingerprint"]))
    widths = [max(len(line[j]) for line in lines) for j in range(len(head))]
    return "\n".join("  ".join(c.ljust(w) for c, w in zip(line, widths)).rstrip() for line in lines)


def shared_names(rows: list[dict]) -> list[str]:
    """A warning per instance name that more than one process uses: the coordinator takes one answer per
    name and drops the other's as duplicates (docs/scaling.md: each instance needs its own node name)."""
    procs: dict[tuple, set] = {}
    for r in rows:
        procs.setdefault((r["discipline"], r["instance"]), set()).add((r["host"], r["pid"]))
    return [f"warning: {len(p)} processes use the instance name {inst} of {disc} ("
            + ", ".join(f"pid {pid} on {host}" for host, pid in sorted(p, key=str))
            + "): their answers count as one instance's; give each its own node name (-r __node:=NAME)"
            for (disc, inst), p in sorted(procs.items()) if len(p) > 1]
