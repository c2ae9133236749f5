"""Errors of the bag layer."""
from __future__ import annotations


class BagError(ValueError):
    """A bag that cannot be used: not MCAP, corrupt, truncated beyond use, foreign schema.

    The message names the file and the problem (the CLI prints it as one line, exit 2).
    """
