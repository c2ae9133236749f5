"""ros/fastwait.until, the one "wait until ready or deadline" loop of ros/: it steps until the
condition holds, and says False once the wait is over (no ROS graph needed)."""
from __future__ import annotations

import time

from bev_mdo.ros.fastwait import until


def test_until_steps_until_ready_and_not_once_more():
    seen = []
    assert until(lambda: len(seen) >= 3, 5.0, lambda: seen.append(1))
    assert seen == [1, 1, 1]
    assert until(lambda: True, 0.0, lambda: seen.append(2)) and seen == [1, 1, 1]  # ready: no step at all


def test_until_gives_up_after_the_wait_having_stepped_meanwhile():
    steps = []
    t0 = time.monotonic()
    assert not until(lambda: False, 0.05, lambda: (steps.append(1), time.sleep(0.01)))
    assert time.monotonic() - t0 >= 0.05 and steps


class _Clock:
    """A clock that moves only when the wait steps (one second per step): the test needs no real time."""

    def __init__(self):
        self.now = 0.0

    def monotonic(self) -> float:
        return self.now

    def step(self) -> None:
        self.now += 1.0


def test_a_start_up_wait_goes_on_while_progress_is_made_and_says_what_it_waits_for(monkeypatch, capsys):
    from bev_mdo.ros import fastwait

    clock = _Clock()
    monkeypatch.setattr(fastwait, "time", clock)
    # something changes every step: ready after 20 s, far past the 3 s bound without progress
    assert until(lambda: clock.now >= 20, 3.0, clock.step, progress=lambda: clock.now, what="energy")
    # nothing changes: gives up once 3 s passed without progress, counting down on stderr meanwhile
    clock.now = 0.0
    assert not until(lambda: False, 3.0, clock.step, progress=lambda: "same", what="energy")
    assert clock.now == 4.0
    lines = capsys.readouterr().err.splitlines()
    assert lines[-1] == "[start-up] waiting for energy; gives up in 1 s without progress"
    # progress for ever, never ready: ends after STARTUP_CAP times the bound in all
    clock.now = 0.0
    assert not until(lambda: False, 3.0, clock.step, progress=lambda: clock.now)
    assert clock.now == fastwait.STARTUP_CAP * 3.0 + 1.0
