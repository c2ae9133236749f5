"""``bev-mdo calibrate``: fit a model's fleet-wide parameters to measured cars and write the set."""
from __future__ import annotations


def register(subparsers) -> None:
    parser = subparsers.add_parser("calibrate", help="fit a model's fleet-wide parameters to a fleet of measured "
                                                     "cars, cross-validated by family and by make")
    from bev_mdo.models.calibrate import add_arguments, run

    add_arguments(parser)
    parser.set_defaults(func=run)
