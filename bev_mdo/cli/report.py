"""``bev-mdo report BAG``: PNG plots and report.md written into the bag directory (``--run-id`` of a recording of
several runs: its ``report_<run_id>`` folder there).

A bag (or --run-id) without iteration records: stderr says what it holds; exit 1 if no plot could be made of it.
"""
from __future__ import annotations

import sys

from bev_mdo.cli.flags import add_bag_argument


def register(subparsers) -> None:
    parser = subparsers.add_parser("report")
    add_bag_argument(parser)
    parser.add_argument("--output-dir", help="write here instead of the bag directory")
    parser.add_argument("--run-id", help="this run (default: the bag's own; needed for a recording of several runs, "
                                         "whose run's report goes to BAG/report_<run_id>/ unless --output-dir)")
    from bev_mdo.cli.history import add_verify_arguments

    add_verify_arguments(parser)
    parser.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.bag.history import check_note
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.report import report

    bag = open_bag(args.bag)
    if bag.truncated:
        print(bag.recovery_note(), file=sys.stderr)
    if bag.metadata_note:
        print(bag.metadata_note, file=sys.stderr)
    checks: dict = {}
    paths = report(bag, args.output_dir, run_id=args.run_id, checks=checks, key_file=args.key_file,
                   no_verify=args.no_verify)
    for path in paths:
        print(path)
    if check_note(checks):
        print(f"{args.bag}: {check_note(checks)}", file=sys.stderr)
    if not checks["iterations"]:  # what it could write is written (a pool's work, say)
        from bev_mdo.cli.history import EXIT_NO_ITERATIONS, no_iterations

        print(f"bev-mdo report: {no_iterations(args, bag, checks)}", file=sys.stderr)
        if len(paths) <= 1:  # report.md alone, with nothing of a run in it, or nothing (another run): as history
            return EXIT_NO_ITERATIONS
    return 0
