"""A discipline call bounded in time in the caller's thread (mdo/timed.py) leaves the caller's own timer alone."""
import signal

import numpy as np

from bev_mdo.mdo.timed import TimedDiscipline


class Double:
    name, inputs, outputs = "double", ["x"], ["y"]

    def compute(self, inputs):
        return {"y": 2 * inputs["x"]}


def test_a_bounded_call_leaves_the_callers_timer_and_handler_running():
    """An API trial: every in-process run set the caller's pending ITIMER_REAL to 0 (its alarm never came)."""
    fired = []

    def mine(*_):
        fired.append(True)

    old = signal.signal(signal.SIGALRM, mine)
    signal.setitimer(signal.ITIMER_REAL, 600.0)
    try:
        out = TimedDiscipline(Double(), timeout_s=5.0).compute({"x": np.array([1.0, 2.0])})
        remaining, _ = signal.getitimer(signal.ITIMER_REAL)
        handler = signal.getsignal(signal.SIGALRM)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    assert list(out["y"]) == [2.0, 4.0]
    assert 0 < remaining <= 600.0 and handler is mine and not fired


def test_without_a_timer_of_the_callers_none_is_left_behind():
    old = signal.getsignal(signal.SIGALRM)
    TimedDiscipline(Double(), timeout_s=5.0).compute({"x": np.array([1.0])})
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0) and signal.getsignal(signal.SIGALRM) is old
