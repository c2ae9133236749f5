"""Jacobi: one call per sweep holding every loop discipline, each reading the previous sweep's
outputs (one request wave per sweep over ROS; OpenMDAO's NonlinearBlockJac, GEMSEO's MDAJacobi).
A cold start seeds every loop input by one sequential pass from the torn-variable guesses."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bev_mdo.mdo.mda.base import Batch
from bev_mdo.mdo.mda.fixed_point import FixedPoint


class Jacobi(FixedPoint):
    name = "jacobi"

    def seed(self, comp: Sequence[str], b: Batch, rows: np.ndarray) -> None:
        for m in comp:
            self.calls.run([m], b, rows[b.ok[rows]])

    def sweep(self, comp: Sequence[str], b: Batch, active: np.ndarray) -> None:
        self.calls.run(list(comp), b, active, relaxation=self.relaxation)
