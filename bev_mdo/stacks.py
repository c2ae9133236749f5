"""``kill -USR1 <pid>`` makes a bev_mdo process print every thread's Python stack to stderr and go
on: where a command or node that seems stuck is waiting (Python's faulthandler). The CLI and every
node executable register it at start."""
from __future__ import annotations

import faulthandler
import signal
import sys


def dump_stacks_on_sigusr1() -> None:
    """Register the SIGUSR1 stack dump on the process's own stderr (no-op where the platform has no
    SIGUSR1, or the process has no stderr file, e.g. an embedding that closed it)."""
    if not hasattr(signal, "SIGUSR1"):
        return
    try:  # the process's stderr, not a capture that replaced sys.stderr (main() called as a library)
        sys.__stderr__.fileno()
    except (AttributeError, OSError, ValueError):
        return
    faulthandler.register(signal.SIGUSR1, file=sys.__stderr__, all_threads=True)
