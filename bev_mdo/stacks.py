"""``kill -USR1 <pid>`` makes a bev_mdo process print every thread's Python stack to stderr and go
on: where a command or node that seems stuck is waiting (Python's faulthandler). The CLI and every
node executable register it at start."""
from __future__ import annotations

import faulthandler
import signal


def dump_stacks_on_sigusr1() -> None:
    """Register the SIGUSR1 stack dump (no-op where the platform has no SIGUSR1)."""
    if hasattr(signal, "SIGUSR1"):
        faulthandler.register(signal.SIGUSR1, all_threads=True)
