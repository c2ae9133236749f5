"""``bev-mdo record [--topics ...] [--output BAG] [--config CONFIG]``: run the recorder node."""
from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser("record", help="record bev_mdo topics to a rosbag2 MCAP bag")
    parser.add_argument("--topics", nargs="+", help="topics to record (default: all under /bev_mdo/)")
    parser.add_argument("--output", "-o", help="bag directory (default bags/<time>_record)")
    parser.add_argument("--config", help="configuration file to store in the bag")
    parser.add_argument("--run-id", help="run id to store in the bag")
    from bev_mdo.cli.ros_args import add_ros_arguments

    add_ros_arguments(parser)
    parser.set_defaults(func=run)


def run(args) -> int:
    from pathlib import Path

    from bev_mdo.ros.recorder_node import main

    argv = []
    if args.output:
        if (Path(args.output) / "metadata.yaml").exists() or list(Path(args.output).glob("*.mcap")):
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
    return main(argv)


def _join_domain(args) -> None:
    """Domain and discovery as every command that talks ROS: flags, the config's ros: section
    (with --config), ROS_DOMAIN_ID, 77."""
    from bev_mdo.cli.ros_args import ros_section
    from bev_mdo.ros.client import apply_ros_environment

    config: dict = {}
    if getattr(args, "config", None):
        import yaml

        from pathlib import Path

        raw = yaml.safe_load(Path(args.config).read_text()) or {}
        config = {"ros": raw.get("ros") or {}} if isinstance(raw, dict) else {}
    apply_ros_environment(ros_section(config, args))
