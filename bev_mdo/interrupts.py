"""SIGINT and SIGTERM that third-party code cannot lose.

The CLI turns both signals into exceptions raised in the main thread (KeyboardInterrupt, and
``Terminated`` for SIGTERM), so every ``finally`` runs and a run's bag is closed. A library that wraps
a line in a bare ``except:`` (pymoo does, around a hash and a dtype cast it runs per individual)
swallows the exception when the signal lands there, and the run goes on. So the handler also keeps
the signal as pending, and the engine's loops call ``check()`` once per batch: a swallowed signal is
raised again at the next batch.
"""
from __future__ import annotations

import contextlib
import signal


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised into the main thread like SIGINT's KeyboardInterrupt; exit status 143."""


_pending: type[BaseException] | None = None
_deferring = 0  # > 0 inside deferred(): a signal is kept and raised at the block's end


def _handler(exc: type[BaseException]):
    def handle(signum, frame) -> None:
        global _pending
        _pending = exc
        if not _deferring:
            raise exc()

    return handle


@contextlib.contextmanager
def deferred():
    """A block that a signal does not cut in two (a bag record written halfway leaves a file no reader can
    open past it): SIGINT or SIGTERM arriving inside is raised when the block ends."""
    global _deferring
    _deferring += 1
    try:
        yield
    finally:
        _deferring -= 1
        if not _deferring and _pending is not None:
            raise _pending()


def install() -> dict:
    """Handlers for SIGTERM and (unless it is ignored, as in a shell's background job) SIGINT;
    returns the previous handlers for ``restore``. Main thread only."""
    global _pending
    _pending = None
    previous = {signal.SIGTERM: signal.signal(signal.SIGTERM, _handler(Terminated))}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        previous[signal.SIGINT] = signal.signal(signal.SIGINT, _handler(KeyboardInterrupt))
    return previous


def restore(previous: dict) -> None:
    for signum, handler in previous.items():
        signal.signal(signum, handler)


def check() -> None:
    """Raise again a signal whose exception was swallowed on the way (a no-op otherwise)."""
    if _pending is not None:
        raise _pending()
