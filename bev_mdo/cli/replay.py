"""``bev-mdo replay BAG [--rate R | --as-fast-as-possible] [--topics ...] [--loop] [--key-file K | --no-verify]``."""
from __future__ import annotations

import sys

from bev_mdo.cli.flags import add_bag_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser("replay")
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
    from bev_mdo.cli.history import add_verify_arguments

    add_verify_arguments(parser)
    add_ros_arguments(parser, config=False)
    parser.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.cli.flags import join_domain
    from bev_mdo.ros.replay import replay

    join_domain(args, where=None)  # the flags, else the environment's ROS_DOMAIN_ID; localhost by default
    rate = None if args.as_fast_as_possible else args.rate
    verify(args)  # a path that is not a bag, or a bag that does not verify, is one error line before anything else
    if args.wait_subscribers:
        print(f"waiting up to {args.wait_timeout:g} s for {args.wait_subscribers} subscriber(s) on each topic "
              "(--no-wait publishes at once) ...", file=sys.stderr, flush=True)
    stats = replay(args.bag, rate=rate, topics=args.topics, loop=args.loop,
                   wait_subscribers=args.wait_subscribers, wait_timeout_s=args.wait_timeout,
                   log=lambda line: print(line, file=sys.stderr))
    print(f"replayed {stats.messages} messages in {stats.seconds:.3f} s "
          f"({stats.messages_per_s:.0f} msg/s)")
    if not stats.messages:  # a bag cut before its first chunk (or topics that hold none): as history, exit 1
        print(f"bev-mdo replay: {args.bag}: nothing to replay" + (f" on {', '.join(args.topics)}" if args.topics else ""),
              file=sys.stderr)
        return 1
    return 0


def verify(args) -> None:
    """Check the bag as ``history`` does before anything is published: a bag whose signing record, stored
    config and key disagree, or with iteration records that do not verify with the run's key, is refused
    (BagError, exit 2; ``--no-verify`` replays it as it is); stderr says when its records are not verified, and
    when they stop before the run's end (its end-of-run record counts more)."""
    from bev_mdo.bag.errors import BagError
    from bev_mdo.bag.history import history
    from bev_mdo.bag.reader import open_bag

    bag = open_bag(args.bag)
    checks: dict = {}
    history(bag, all_runs=True, key_file=args.key_file, checks=checks, no_verify=args.no_verify)
    failed = {why: n for why, n in checks["dropped"].items() if why in ("forged", "unsigned")}
    if failed:
        counts = ", ".join(f"{n} {why}" for why, n in sorted(failed.items()))
        raise BagError(f"{bag.mcap_path}: {counts} iteration record(s) (not signed with the run's key); "
                       "refusing to replay it (--no-verify replays it as is)")
    if checks["unverified"]:
        print(f"{args.bag}: {checks['unverified']}", file=sys.stderr)
    if checks.get("tail"):  # its end-of-run record counts records past the bag's last: said as history says it
        print(f"{args.bag}: {checks['tail']}", file=sys.stderr)
