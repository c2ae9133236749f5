"""Gauss-Seidel: one call per discipline per sweep, in the loop's declared order, each reading the
outputs its predecessors produced in the same sweep (OpenMDAO's NonlinearBlockGS, GEMSEO's
MDAGaussSeidel)."""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bev_mdo.mdo.mda.base import Batch
from bev_mdo.mdo.mda.fixed_point import FixedPoint


class GaussSeidel(FixedPoint):
    name = "gauss_seidel"

    def sweep(self, comp: Sequence[str], b: Batch, active: np.ndarray) -> None:
        for m in comp:
            self.calls.run([m], b, active[b.ok[active]], relaxation=self.relaxation)
