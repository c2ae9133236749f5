"""``bev-mdo record [--topics ...] [--output BAG] [--config CONFIG]``: run the recorder node."""
from __future__ import annotations

import os
from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser("record")
    parser.add_argument("--topics", nargs="+", help="topics to record (default: all under /bev_mdo/)")
    parser.add_argument("--output", "-o", help="bag directory (default bags/<time>_record)")
    parser.add_argument("--config", help="configuration file to store in the bag")
    parser.add_argument("--run-id", help="run id to store in the bag")
    from bev_mdo.cli.flags import add_ros_arguments

    add_ros_arguments(parser)
    parser.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.ros.recorder_node import main

    argv = []
    if args.output:
        from bev_mdo.bag.reader import holds_bag

        if holds_bag(args.output):
            raise ValueError(f"{args.output}: bag already exists")
        argv += ["--output", args.output]
    if args.topics:
        argv += ["--topics", *args.topics]
    if args.config:
        if not Path(args.config).is_file():
            raise ValueError(f"{args.config}: no such configuration file")
        argv += ["--config", args.config]
    if args.run_id:
        argv += ["--run-id", args.run_id]
    _join_domain(args)
    status = main(argv)
    from bev_mdo import interrupts

    interrupts.clear()  # Ctrl-C or SIGTERM is how a recording ends (exit 0, as for `ros2 bag record`)
    return status


def _join_domain(args, where: str | None = "record") -> None:
    """Domain and discovery of a recording or a replay: the flags, over the --config file's ros: section (record's),
    else a valid ROS_DOMAIN_ID of the environment (localhost by default: never off-host unasked). A bad value is
    said after the file's name, or ``where`` (None: as it is)."""
    from bev_mdo.api.transport import ros_section
    from bev_mdo.ros.client import apply_ros_environment

    ros, env = {}, os.environ.get("ROS_DOMAIN_ID", "")
    if getattr(args, "config", None):
        from bev_mdo.yamlload import load_yaml

        try:
            raw = load_yaml(Path(args.config).read_text(encoding="utf-8"))
        except Exception as exc:  # yaml.YAMLError and friends: one line naming the file
            raise ValueError(f"{args.config}: not valid YAML: {str(exc).splitlines()[0]}") from None
        ros = (raw.get("ros") or {}) if isinstance(raw, dict) else {}
    if "domain_id" not in ros and env.isdigit():
        ros = {"domain_id": int(env), **ros}
    try:
        apply_ros_environment(ros_section({"ros": ros}, args))
    except ValueError as exc:
        if not (getattr(args, "config", None) or where):
            raise
        raise ValueError(f"{getattr(args, 'config', None) or where}: {exc}") from None
