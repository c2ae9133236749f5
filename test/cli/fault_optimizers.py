"""`bev-mdo` with two more optimisers, for tests of what stops a run: ``python fault_optimizers.py optimize CONFIG
--optimizer NAME ...`` (test/cli/test_interrupt_bag.py, test/ros/test_kill.py).

* ``failing-after-3`` raises in the coordinator (not in a discipline) at its fourth iteration;
* ``waiting-after-2`` stops after its second iteration until a line arrives on stdin (the test then has
  done what it wanted to do mid-run), then makes two more iterations and returns.

Both are plain batch optimisers (the registry's ``module:function`` plug-in form): each iteration evaluates
a small batch around the best point so far through the run's evaluator (in process or over ROS) and reports
the best through the callback (an iteration record)."""
from __future__ import annotations

import sys

import numpy as np
from scipy.optimize import OptimizeResult

FAILURE = "the failing-after-3 optimiser fails on purpose"


def _iteration(batch_fun, x, lower, upper, callback):
    step = 0.05 * (np.asarray(upper, float) - np.asarray(lower, float))
    candidates = np.clip(np.vstack([x, x + step, x - step]), lower, upper)
    f, g = batch_fun(candidates)
    feasible = np.max(g, axis=1, initial=0.0) <= 0.0
    x = candidates[np.lexsort((f, ~feasible))[0]]  # feasible first, then the lowest objective
    callback(x)
    return x


def failing_after_3(batch_fun, x0, lower, upper, options, callback):
    x = np.asarray(x0, dtype=float)
    for _ in range(3):
        x = _iteration(batch_fun, x, lower, upper, callback)
    raise RuntimeError(FAILURE)


def waiting_after_2(batch_fun, x0, lower, upper, options, callback):
    x = np.asarray(x0, dtype=float)
    for i in range(4):
        if i == 2:
            sys.stdin.readline()
        x = _iteration(batch_fun, x, lower, upper, callback)
    return OptimizeResult(x=x, success=True, message="four iterations made")


if __name__ == "__main__":
    from bev_mdo.cli import main
    from bev_mdo.mdo import optimizers

    optimizers.OPTIMIZERS["failing-after-3"] = "fault_optimizers:failing_after_3"
    optimizers.OPTIMIZERS["waiting-after-2"] = "fault_optimizers:waiting_after_2"
    sys.exit(main())
