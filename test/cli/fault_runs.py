"""`bev-mdo` whose coordinator fails or pauses at a known point of a `pareto` or `sweep` run, for tests of what
stops a run (test_interrupt_bag.py): ``python fault_runs.py POINT COMMAND ...`` with POINT one of

* ``fail-after-generation-3``: ``pareto`` raises in the coordinator once its third generation is done;
* ``fail-after-batch``: ``sweep`` raises in the coordinator once its batch is done (writing the CSV);
* ``pause-in-batch``: ``sweep`` prints ``paused`` on stdout as its batch starts (the discipline nodes are up)
  and waits for a line on stdin or a signal;
* ``pause-after-3-records``: ``sweep`` prints ``paused`` on stdout once three designs are in its bag and
  waits for a line on stdin or a signal.

A paused run waits where the test wants to stop it (with a signal): no sleeps, no racing the run."""
from __future__ import annotations

import sys

FAILURE = "the coordinator fails on purpose"


def _pause() -> None:
    """Say ``paused`` and wait for a line on stdin or a signal. Not a read of stdin alone: a signal that lands after the
    interpreter's last look at its signals and before the read (a loaded host preempts the run there), or in another
    thread, does not interrupt the read, and the run waited for good. The signal's wakeup fd (written by its C handler,
    whenever and wherever it runs) ends the wait; the handler then raises in this thread as the call returns."""
    import os
    import select
    import signal

    wake, woken = os.pipe()
    os.set_blocking(woken, False)
    previous = signal.set_wakeup_fd(woken)
    try:
        print("paused", flush=True)
        ready, _, _ = select.select([sys.stdin, wake], [], [])
    finally:
        signal.set_wakeup_fd(previous)
        os.close(wake)
        os.close(woken)
    if sys.stdin in ready:
        sys.stdin.readline()


def fail_after_generation_3() -> None:
    from bev_mdo.cli import pareto

    show = pareto._generation

    def generation(g, n, s):
        show(g, n, s)
        if g >= 3:
            raise RuntimeError(FAILURE)

    pareto._generation = generation


def fail_after_batch() -> None:
    from bev_mdo.cli import sweep

    def write_csv(path, result):
        raise RuntimeError(FAILURE)

    sweep.write_csv = write_csv


def pause_in_batch() -> None:
    from bev_mdo.mdo import driver

    make = driver._mda

    def mda(*args, **kwargs):
        m = make(*args, **kwargs)
        run = m.run

        def paused_run(*a, **kw):
            _pause()
            return run(*a, **kw)

        m.run = paused_run
        return m

    driver._mda = mda


def pause_after_3_records() -> None:
    from bev_mdo.api.runbag import InProcessBag

    write = InProcessBag.__call__

    def call(self, rec):
        write(self, rec)
        if rec["iteration"] == 2:  # the third design
            _pause()

    InProcessBag.__call__ = call


if __name__ == "__main__":
    from bev_mdo.cli import main

    {"fail-after-generation-3": fail_after_generation_3, "fail-after-batch": fail_after_batch,
     "pause-in-batch": pause_in_batch, "pause-after-3-records": pause_after_3_records}[sys.argv.pop(1)]()
    sys.exit(main())
