"""Standard test functions of global sensitivity analysis, as user disciplines (batched numpy).

* ``Ishigami``: f = sin x1 + a sin^2 x2 + b x3^4 sin x1 on [-pi, pi]^3 (Ishigami & Homma 1990),
  a = 7, b = 0.1: S1 = 0.3139, 0.4424, 0; ST = 0.5576, 0.4424, 0.2437.
* ``GFunction``: Sobol's g = prod (|4 x_i - 2| + a_i) / (1 + a_i) on [0, 1]^8 with
  a = 0, 1, 4.5, 9, 99, 99, 99, 99 (Saltelli et al. 2000); its indices have a closed form
  (``g_indices``).
"""
from __future__ import annotations

import numpy as np

G_A = (0.0, 1.0, 4.5, 9.0, 99.0, 99.0, 99.0, 99.0)


class Ishigami:
    name = "ishigami"
    inputs = ("x1", "x2", "x3")
    outputs = ("f",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    a, b = 7.0, 0.1

    def compute(self, inputs):
        x1, x2, x3 = inputs["x1"], inputs["x2"], inputs["x3"]
        return {"f": np.sin(x1) + self.a * np.sin(x2) ** 2 + self.b * x3 ** 4 * np.sin(x1)}


class GFunction:
    name = "g_function"
    inputs = tuple(f"x{i + 1}" for i in range(len(G_A)))
    outputs = ("g",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        g = np.ones_like(np.asarray(inputs["x1"], dtype=float))
        for i, a in enumerate(G_A):
            g = g * (np.abs(4.0 * inputs[f"x{i + 1}"] - 2.0) + a) / (1.0 + a)
        return {"g": g}


def g_indices(a=G_A) -> tuple[np.ndarray, np.ndarray]:
    """(S1, ST) of the G function: V_i = 1 / (3 (1 + a_i)^2), V = prod(1 + V_i) - 1."""
    v = 1.0 / (3.0 * (1.0 + np.asarray(a, dtype=float)) ** 2)
    total = np.prod(1.0 + v) - 1.0
    st = np.array([v[i] * np.prod(np.delete(1.0 + v, i)) for i in range(len(v))]) / total
    return v / total, st
