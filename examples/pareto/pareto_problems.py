"""Two-objective test problems from the literature, with analytic Pareto fronts, as user disciplines
for ``bev-mdo pareto`` (one discipline each; configs beside this file).

* ZDT1 (Zitzler, Deb, Thiele 2000), unconstrained, n variables in [0, 1]:
  f1 = x1, g = 1 + 9 sum(x2..xn) / (n - 1), f2 = g (1 - sqrt(f1 / g));
  front: f2 = 1 - sqrt(f1), f1 in [0, 1] (x2..xn = 0).
* SRN (Srinivas, Deb 1994), x in [-20, 20]^2: f1 = 2 + (x1 - 2)^2 + (x2 - 1)^2, f2 = 9 x1 - (x2 - 1)^2,
  c1 = x1^2 + x2^2 <= 225, c2 = x1 - 3 x2 + 10 <= 0. Where no constraint is active, grad f1 and grad f2
  are opposed only on x1 = -2.5 (KKT with weights 1/2), so the front is the non-dominated part of that
  line (from x2 = 2.5, where c2 is active) and of the constraint boundaries c1 = 0 and c2 = 0: the
  line up to the circle, then an arc of the circle x1^2 + x2^2 = 225 (often left out in the literature).
* TNK (Tanaka et al. 1995), x in [0, pi]^2 (x1 from 1e-12: atan(x2 / x1)): f1 = x1, f2 = x2,
  c1 = x1^2 + x2^2 - 1 - 0.1 cos(16 atan(x1 / x2)) >= 0, c2 = (x1 - 0.5)^2 + (x2 - 0.5)^2 <= 0.5;
  front: the non-dominated part of the curve c1 = 0 inside c2 (disconnected), wholly set by a constraint.

``analytic_front(points)`` of each class samples its front in objective space (rows (f1, f2)).
"""
from __future__ import annotations

import numpy as np


class ZDT1:
    """x1..xn -> f1, f2 (ZDT1)."""

    name = "zdt1"
    outputs = ("f1", "f2")

    def __init__(self, n: int = 6):
        if isinstance(n, bool) or not isinstance(n, int) or n < 2:
            raise ValueError(f"n must be an integer >= 2, got {n!r}")
        self.n = n
        self.inputs = tuple(f"x{i}" for i in range(1, n + 1))
        self.units = dict.fromkeys(self.inputs + self.outputs, "1")  # dimensionless

    def compute(self, inputs):
        x = np.column_stack([inputs[k] for k in self.inputs])
        g = 1.0 + 9.0 * x[:, 1:].sum(axis=1) / (self.n - 1)
        f1 = x[:, 0]
        return {"f1": f1, "f2": g * (1.0 - np.sqrt(np.clip(f1, 0.0, None) / g))}

    @staticmethod
    def analytic_front(points: int = 2001) -> np.ndarray:
        f1 = np.linspace(0.0, 1.0, points)
        return np.column_stack([f1, 1.0 - np.sqrt(f1)])


class SRN:
    """x1, x2 -> f1, f2, c1, c2 (SRN)."""

    name = "srn"
    inputs = ("x1", "x2")
    outputs = ("f1", "f2", "c1", "c2")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        x1, x2 = inputs["x1"], inputs["x2"]
        return {"f1": 2.0 + (x1 - 2.0) ** 2 + (x2 - 1.0) ** 2, "f2": 9.0 * x1 - (x2 - 1.0) ** 2,
                "c1": x1 ** 2 + x2 ** 2, "c2": x1 - 3.0 * x2 + 10.0}

    @staticmethod
    def analytic_front(points: int = 20001) -> np.ndarray:
        line = np.column_stack([np.full(points, -2.5), np.linspace(-20.0, 20.0, points)])  # interior KKT
        t = np.linspace(0.0, 2.0 * np.pi, points)
        circle = 15.0 * np.column_stack([np.cos(t), np.sin(t)])                               # c1 active
        x1 = np.linspace(-20.0, 20.0, points)
        c2 = np.column_stack([x1, (x1 + 10.0) / 3.0])                                         # c2 active
        x = np.concatenate([line, circle, c2])
        x = x[(x[:, 0] ** 2 + x[:, 1] ** 2 <= 225.0 + 1e-9) & (x[:, 0] - 3.0 * x[:, 1] + 10.0 <= 1e-9)]
        f = np.column_stack([2.0 + (x[:, 0] - 2.0) ** 2 + (x[:, 1] - 1.0) ** 2, 9.0 * x[:, 0] - (x[:, 1] - 1.0) ** 2])
        return _non_dominated_2d(f)


class TNK:
    """x1, x2 -> f1, f2, c1, c2 (TNK)."""

    name = "tnk"
    inputs = ("x1", "x2")
    outputs = ("f1", "f2", "c1", "c2")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        x1, x2 = inputs["x1"], inputs["x2"]
        return {"f1": x1 + 0.0, "f2": x2 + 0.0,
                "c1": x1 ** 2 + x2 ** 2 - 1.0 - 0.1 * np.cos(16.0 * np.arctan2(x1, x2)),
                "c2": (x1 - 0.5) ** 2 + (x2 - 0.5) ** 2}

    @staticmethod
    def analytic_front(points: int = 20001) -> np.ndarray:
        phi = np.linspace(0.0, np.pi / 2, points)  # angle from the x2 axis: atan(x1 / x2) = phi
        r = np.sqrt(1.0 + 0.1 * np.cos(16.0 * phi))
        f = np.column_stack([r * np.sin(phi), r * np.cos(phi)])
        return _non_dominated_2d(f[(f[:, 0] - 0.5) ** 2 + (f[:, 1] - 0.5) ** 2 <= 0.5])


def _non_dominated_2d(f: np.ndarray) -> np.ndarray:
    """The rows of f (N, 2) no other row dominates (both minimised), sorted by f1."""
    f = f[np.lexsort((f[:, 1], f[:, 0]))]
    best = np.minimum.accumulate(f[:, 1])  # sweep by f1: dominated when an earlier row has f2 <= its own
    keep = np.ones(len(f), bool)
    keep[1:] = f[1:, 1] < best[:-1]
    return f[keep]
