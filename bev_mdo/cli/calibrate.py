"""``bev-mdo calibrate``: fit a model's fleet-wide parameters to measured cars and write the set."""
from __future__ import annotations


def register(subparsers) -> None:
    from bev_mdo.models.calibrate import DESCRIPTION, add_arguments, run

    parser = subparsers.add_parser("calibrate", description=DESCRIPTION)
    add_arguments(parser)
    parser.set_defaults(func=run)
