"""``bev-mdo bag info|repair BAG``: inspect or repair a recorded bag."""
from __future__ import annotations

import sys

from bev_mdo.cli.flags import add_bag_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser("bag")
    sub = parser.add_subparsers(dest="bag_command", metavar="ACTION")
    sub.required = True
    info = sub.add_parser("info", help="topics, message counts and duration of a bag")
    add_bag_argument(info)
    info.set_defaults(func=run)
    rep = sub.add_parser("repair", help="rebuild summary and metadata.yaml of a truncated bag")
    add_bag_argument(rep)
    rep.add_argument("--force", action="store_true", help="rewrite even a complete bag")
    rep.set_defaults(func=run)


def run(args) -> int:
    if args.bag_command == "repair":
        from bev_mdo.bag.repair import repair

        result = repair(args.bag, force=args.force)
        if not result.rewritten and not result.was_truncated:
            done = "written (it was missing or did not describe the bag)" if result.metadata_written else "checked"
            print(f"{result.mcap_path}: complete; metadata.yaml {done} ({result.message_count} messages)")
        else:
            total = f" of {result.written_count}" if result.written_count is not None else ""
            print(f"{result.mcap_path}: repaired, {result.message_count}{total} messages kept; "
                  f"{result.damage + '; ' if result.damage else ''}original kept as {result.backup_path}")
        return 0
    from bev_mdo.bag.reader import open_bag

    bag = open_bag(args.bag, strict=False)
    print(f"file:      {bag.mcap_path} ({bag.file_size} bytes)")
    print(f"version:   {bag.info.get('version', '?')}   run_id: {bag.info.get('run_id', '?')}")
    print(f"messages:  {bag.message_count}   duration: {bag.duration_ns / 1e9:.3f} s")
    width = max([len(t) for t in bag.topics] + [5])
    for topic, type_name in sorted(bag.topics.items()):
        print(f"  {topic:<{width}}  {bag.counts.get(topic, 0):>8}  {type_name}")
    if bag.truncated:
        print(bag.recovery_note(), file=sys.stderr)
    if bag.metadata_note:
        print(bag.metadata_note, file=sys.stderr)
    if not any(t.startswith("bev_mdo_msgs/") for t in bag.topics.values()):  # listed as it is, as ros2 bag info
        print(f"{bag.mcap_path}: no bev_mdo_msgs schema: not a bev_mdo recording (history, report, resume and replay "
              "refuse it)", file=sys.stderr)
    return 0
