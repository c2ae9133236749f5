"""The ``bev-mdo`` command line. One module per subcommand, each with ``register(subparsers)``.

A user mistake (bad config, bad value, bad file) prints one line on stderr and exits 2.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

# Subcommand modules in bev_mdo.cli, in the order --help lists them.
SUBCOMMANDS = (
    "optimize", "evaluate", "node", "record", "replay", "history", "report",
    "resume", "bag", "sensitivity", "pareto", "sweep", "graph", "validate", "check_partials", "status",
)


class UsageError(Exception):
    """A mistake by the user: reported as one line on stderr, exit status 2."""


def build_parser() -> argparse.ArgumentParser:
    from bev_mdo import __version__

    parser = argparse.ArgumentParser(
        prog="bev-mdo",
        description="Distributed MDO of battery-electric-vehicle powertrains over ROS 2.",
    )
    parser.add_argument("--version", action="version", version=f"bev-mdo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"bev_mdo.cli.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"bev_mdo.cli.{name}":
                continue  # subcommand not built yet
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("bev-mdo: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return _closed_pipe()
    except (UsageError, ValueError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        msg = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        print(f"bev-mdo {args.command}: error: {msg}", file=sys.stderr)
        return 2


def _closed_pipe() -> int:
    """The reader of stdout went away (``bev-mdo bag info BAG | head``): stop quietly, like a
    command killed by SIGPIPE (exit status 141), without a traceback at interpreter exit."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass
    return 141


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
