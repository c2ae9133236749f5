"""`bev-mdo node NAME`: run one discipline node in this process (like `ros2 run bev_mdo NAME_node`)."""
from __future__ import annotations

import os
import re

from bev_mdo.api.errors import InputError


def register(sub) -> None:
    p = sub.add_parser("node", description="Run one discipline as a ROS 2 node until Ctrl-C. Discovery stays on this host "
                                   "unless the config's ros: section opts in to more.")
    p.add_argument("name", help="discipline name, e.g. energy")
    p.add_argument("--config", default=None, help="run config YAML (default: config/leaf_nedc.yaml)")
    p.add_argument("--instance", default="",
                   help="instance suffix (letters, digits, _), to run several copies of one discipline")
    from bev_mdo.cli.flags import add_ros_arguments

    add_ros_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.config import RunConfig
    from bev_mdo.ros.paths import default_config

    if args.instance and not re.fullmatch(r"[A-Za-z0-9_]+", args.instance):  # it becomes part of the node name
        raise InputError(f"--instance {args.instance!r}: use only letters, digits and _ "
                         "(it becomes part of the ROS node name)")
    path = args.config or default_config()
    config = RunConfig.load(path)
    names = list(config.names)
    if args.name not in names:
        raise InputError(f"no discipline {args.name!r} in {path}; it has {names}")
    from bev_mdo.api.transport import ros_section

    ros = ros_section(config, args)
    from bev_mdo.ros.client import apply_ros_environment

    apply_ros_environment(ros)
    from bev_mdo.ros.discipline_node import main

    node_name = f"{args.name}_node" + (f"_{args.instance}" if args.instance else "")
    ros_args = ["--ros-args", "-p", f"config:={os.path.abspath(path)}", "-p", f"discipline:={args.name}",
                "-r", f"__node:={node_name}"]
    status = main(ros_args, discipline=args.name, config=config)
    from bev_mdo import interrupts

    interrupts.clear()  # Ctrl-C or SIGTERM is how a node's service ends (exit 0), not an interruption
    return status
