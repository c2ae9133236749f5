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
