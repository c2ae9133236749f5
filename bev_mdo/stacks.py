"""``kill -USR1 <pid>`` makes a bev_mdo process print every thread's Python stack to stderr and go
on: where a command or node that seems stuck is waiting (Python's faulthandler). The CLI and every
node executable register it at start."""
from __future__ import annotations

import contextlib
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


TEARDOWN_S = 30.0  # destroying a node and shutting a context down takes well under a second, seconds under load


@contextlib.contextmanager
def deadline(seconds: float = TEARDOWN_S):
    """The block must end within `seconds`, or the process ends: every thread's stack is printed on stderr
    (faulthandler's ``Timeout (0:00:30)!``) and the process exits with status 1.

    For the ROS teardown of the coordinator's process: when its DDS participant is hung (a Fast DDS deadlock,
    docs/security.md), destroying it blocks for good, with or without Python's lock, and a run would never
    end. The launched nodes then get SIGTERM from the kernel (they die with their parent). A process-wide
    timer (faulthandler has one): a later `deadline` replaces an earlier one."""
    try:
        sys.__stderr__.fileno()
    except (AttributeError, OSError, ValueError):  # no stderr to print to: no deadline
        yield
        return
    faulthandler.dump_traceback_later(seconds, exit=True, file=sys.__stderr__)
    try:
        yield
    finally:
        faulthandler.cancel_dump_traceback_later()
