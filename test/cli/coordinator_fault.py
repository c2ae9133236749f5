"""`bev-mdo` with one more optimiser, ``failing-after-3``, that raises in the coordinator (not in a
discipline) after three iterations: ``python coordinator_fault.py optimize CONFIG --optimizer failing-after-3 ...``
(test_interrupt_bag.py). It is a plain batch optimiser (the registry's ``module:function`` plug-in form): each
iteration evaluates a small batch around the best point so far through the run's evaluator (in process or over
ROS), reports the best through the callback (an iteration record), and the fourth iteration raises."""
from __future__ import annotations

import sys

import numpy as np
from scipy.optimize import OptimizeResult

ITERATIONS_BEFORE_FAILURE = 3
MESSAGE = "the failing-after-3 optimiser fails on purpose"


def minimize(batch_fun, x0, lower, upper, options, callback):
    x = np.asarray(x0, dtype=float)
    step = 0.05 * (np.asarray(upper, float) - np.asarray(lower, float))
    for iteration in range(ITERATIONS_BEFORE_FAILURE + 1):
        if iteration == ITERATIONS_BEFORE_FAILURE:
            raise RuntimeError(MESSAGE)
        candidates = np.clip(np.vstack([x, x + step, x - step]), lower, upper)
        f, g = batch_fun(candidates)
        feasible = np.max(g, axis=1, initial=0.0) <= 0.0
        order = np.lexsort((f, ~feasible))  # feasible first, then the lowest objective
        x = candidates[order[0]]
        callback(x)
    return OptimizeResult(x=x, success=True, message="unreachable")


if __name__ == "__main__":
    from bev_mdo.cli import main
    from bev_mdo.mdo import optimizers

    optimizers.OPTIMIZERS["failing-after-3"] = "coordinator_fault:minimize"
    sys.exit(main())
