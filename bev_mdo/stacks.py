"""``kill -USR1 <pid>`` makes a bev_mdo process print every thread's Python stack to stderr and go
on: where a command or node that seems stuck is waiting (Python's faulthandler). The CLI and every
node executable register it at start."""
from __future__ import annotations

import contextlib
import faulthandler
import math
import os
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


STARTUP_GAVE_UP_STATUS = 6


class StartupGaveUp(ValueError):
    """A ROS start-up wait gave up: a node or the run's recorder did not appear, match or answer while
    nothing changed for ``ros.discovery_wait_s``, or not within 10 times that in all (ros/fastwait.py).
    The CLI prints it on one line and exits with status 6 (STARTUP_GAVE_UP_STATUS)."""


TEARDOWN_S = 30.0  # destroying a node and shutting a context down takes well under a second, seconds under load
HUNG_TEARDOWN_STATUS = 128 + signal.SIGALRM  # 142: the exit status of a process whose teardown overran its bound


def _stderr_ok() -> bool:
    try:
        sys.__stderr__.fileno()
        return True
    except (AttributeError, OSError, ValueError):
        return False


@contextlib.contextmanager
def deadline(seconds: float = TEARDOWN_S):
    """The block must end within `seconds`, or the process ends: every thread's stack is printed on stderr
    (faulthandler's ``Timeout (0:00:30)!``) and a second later the kernel ends the process with SIGALRM
    (exit status 142, HUNG_TEARDOWN_STATUS; -14 as subprocess reports it).

    For the ROS teardown of a process: when its DDS participant is hung (a Fast DDS deadlock,
    docs/security.md), or a participant being deleted busy-waits for a discovery callback that does not
    end (eProsima/Fast-DDS#6513), destroying it blocks for good, with or without Python's lock, and a run
    would never end. The kernel's SIGALRM needs neither. Launched nodes then get SIGTERM from the kernel
    (they die with their parent), which their Python handler takes only between C calls: their own
    teardown is bounded the same way, or a node hung in it outlives its run (seen: 20 minutes in
    ``destroy_publisher`` after a crowded start-up). Process-wide timers: a later `deadline` replaces an earlier one."""
    if not _stderr_ok():  # no stderr to print to: no deadline
        yield
        return
    import threading

    main = threading.current_thread() is threading.main_thread()  # signal handlers: main thread only
    # elsewhere faulthandler ends the process itself, with status 1
    faulthandler.dump_traceback_later(seconds, exit=not main, file=sys.__stderr__)
    previous = signal.signal(signal.SIGALRM, signal.SIG_DFL) if main else None
    if main:
        signal.alarm(math.ceil(seconds) + 1)
    try:
        yield
    finally:
        if main:
            signal.alarm(0)
            signal.signal(signal.SIGALRM, previous)
        faulthandler.cancel_dump_traceback_later()


_deferred: list | None = None  # teardowns left for the process's exit (defer_teardowns); None: run them at once


def defer_teardowns() -> None:
    """From now on, `teardown` leaves its work for this process's exit (atexit, main thread), after the
    command has printed its result: for the `bev-mdo` process, whose exit `bound_exit` bounds. A
    participant hung in the middleware then costs the exit status (142), not the printed result."""
    global _deferred
    if _deferred is None:
        import atexit

        _deferred = []
        atexit.register(_run_deferred)


def _run_deferred() -> None:
    if not _deferred:
        return
    # a Ctrl-C or SIGTERM here ends the process at once with its line (interrupts.work_done): the result is out
    with deadline(TEARDOWN_S):  # a hang prints every stack, as at once; then the rest of the exit is bounded again
        while _deferred:
            with contextlib.suppress(Exception):
                _deferred.pop(0)()  # in the order they were left: a node before its context
    bound_exit(TEARDOWN_S)


def teardown(close) -> None:
    """Run `close`, the ROS teardown of a participant whose work is done, within `deadline`; or, after
    `defer_teardowns`, at the process's exit."""
    if _deferred is not None:
        _deferred.append(close)
        return
    with deadline(), contextlib.suppress(Exception):
        close()


def end_process(status: int) -> None:
    """End the ``bev-mdo`` process, its work done: its exit handlers (atexit: the deferred ROS teardowns,
    logging, temporary directories), stdout and stderr flushed, then ``os._exit(status)``. Python's own
    finalization is skipped: CPython resets SIGINT to its default action before it tears the modules down
    (0.1-0.2 s), so a Ctrl-C there ended the process silently (exit 130, no line), and it has nothing left to
    release. Returns, leaving the interpreter's exit as usual, while another non-daemon thread runs (the
    exit waits for it) or an rclpy context is still up (its C++ destructors release the middleware)."""
    import atexit
    import threading

    if any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread()):
        return
    atexit._run_exitfuncs()
    context = sys.modules.get("rclpy.context")
    if context is not None and getattr(context, "g_logging_ref_count", 1) > 0:  # a context not shut down
        return
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    os._exit(status)


def bound_exit(seconds: float = TEARDOWN_S) -> None:
    """The process must be gone within `seconds` from now, its interpreter's exit included, or the kernel
    ends it with SIGALRM (exit status 142). For the end of a `bev-mdo` process that ran ROS: after Python's
    own exit, C++ destructors of Fast DDS run where no Python timer does (the factory's destructor waits
    for any participant still being deleted in another thread). Main thread only."""
    signal.signal(signal.SIGALRM, signal.SIG_DFL)
    signal.alarm(max(1, math.ceil(seconds)))
