"""``bev-mdo replay BAG [--rate R | --as-fast-as-possible] [--topics ...] [--loop]``."""
from __future__ import annotations

import sys

from bev_mdo.cli.flags import add_bag_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser("replay", help="publish the messages of a recorded bag again")
    add_bag_argument(parser)
    speed = parser.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=1.0,
                       help="recorded timing scaled by this factor (default 1.0)")
    speed.add_argument("--as-fast-as-possible", action="store_true", help="no timing at all")
    parser.add_argument("--topics", nargs="+", help="only these topics")
    parser.add_argument("--loop", action="store_true", help="start again at the end (Ctrl-C stops)")
    parser.add_argument("--wait-subscribers", type=int, default=1, metavar="N",
                        help="wait until each topic has N subscribers before publishing (default 1)")
    parser.add_argument("--no-wait", dest="wait_subscribers", action="store_const", const=0,
                        help="publish at once, whether anything subscribes or not")
    parser.add_argument("--wait-timeout", type=float, default=30.0, metavar="S",
                        help="give up waiting for subscribers after S seconds (default 30)")
    from bev_mdo.cli.flags import add_ros_arguments

    add_ros_arguments(parser, config=False)
    parser.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.api.transport import ros_section
    from bev_mdo.ros.client import apply_ros_environment
    from bev_mdo.ros.replay import replay

    # Domain and discovery from the flags (else the environment's ROS_DOMAIN_ID; localhost by default):
    # a replay never goes off-host unasked.
    apply_ros_environment(ros_section({"ros": _env_domain()}, args))
    rate = None if args.as_fast_as_possible else args.rate
    if args.wait_subscribers:
        from bev_mdo.bag.reader import open_bag

        open_bag(args.bag)  # a path that is not a bag is one error line, before any word of waiting
        print(f"waiting up to {args.wait_timeout:g} s for {args.wait_subscribers} subscriber(s) on each topic "
              "(--no-wait publishes at once) ...", file=sys.stderr, flush=True)
    stats = replay(args.bag, rate=rate, topics=args.topics, loop=args.loop,
                   wait_subscribers=args.wait_subscribers, wait_timeout_s=args.wait_timeout,
                   log=lambda line: print(line, file=sys.stderr))
    print(f"replayed {stats.messages} messages in {stats.seconds:.3f} s "
          f"({stats.messages_per_s:.0f} msg/s)")
    return 0


def _env_domain() -> dict:
    """{"domain_id": N} from a valid ROS_DOMAIN_ID in the environment, else {} (the default domain)."""
    import os

    value = os.environ.get("ROS_DOMAIN_ID", "")
    return {"domain_id": int(value)} if value.isdigit() else {}
