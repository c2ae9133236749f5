"""``bev-mdo record [--topics ...] [--output BAG] [--config CONFIG]``: run the recorder node."""
from __future__ import annotations

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
    from bev_mdo.cli.flags import join_domain
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
    join_domain(args)
    status = main(argv)
    from bev_mdo import interrupts

    interrupts.clear()  # Ctrl-C or SIGTERM is how a recording ends (exit 0, as for `ros2 bag record`)
    return status

