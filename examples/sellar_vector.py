"""The Sellar problem with vector variables and analytic partials, through the user interface only.

Source: R. S. Sellar, S. M. Batill, J. E. Renaud, "Response surface based, concurrent subspace
optimization for multidisciplinary system design", AIAA 96-0714, 1996; written here as OpenMDAO
writes it (openmdao.test_suite.components.sellar, "SellarDerivatives"): the global design
variable z is ONE vector of two elements, x is local, y1 <-> y2 is a feedback loop.

    y1 = z[0]^2 + z[1] + x - 0.2 y2            (discipline 1)
    y2 = sqrt(y1) + z[0] + z[1]                (discipline 2)
    min  obj = x^2 + z[1] + y1 + exp(-y2)
    s.t. con[0] = 3.16 - y1 <= 0,  con[1] = y2 - 24 <= 0,
         -10 <= z[0] <= 10, 0 <= z[1] <= 10, 0 <= x <= 10

Reference optimum (Sellar et al. 1996; OpenMDAO's documentation and test suite):
obj = 3.18339395 at z = (1.977639, 0), x = 0 (y1 = 3.16, con[0] active).

Each discipline declares its vectors in ``shapes`` and provides ``compute_partials`` with
arrays of shape (N, out_size, in_size); bev_mdo does the rest (docs/vector-variables.md,
docs/derivatives.md). config: examples/sellar_vector.yaml.
"""
from __future__ import annotations

import numpy as np

REFERENCE = {"objective": 3.18339395, "z": (1.977639, 0.0), "x": 0.0}


class SellarDis1:
    name = "sellar_dis1"
    inputs = ("z", "x", "y2")
    outputs = ("y1",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"z": 2}

    def compute(self, inputs):
        z = inputs["z"]  # (N, 2)
        return {"y1": z[:, 0] ** 2 + z[:, 1] + inputs["x"] - 0.2 * inputs["y2"]}

    def compute_partials(self, inputs):
        z = inputs["z"]
        n = len(z)
        dz = np.stack([2.0 * z[:, 0], np.ones(n)], axis=1)[:, None, :]  # (N, 1, 2)
        return {("y1", "z"): dz, ("y1", "x"): np.ones(n), ("y1", "y2"): np.full(n, -0.2)}


class SellarDis2:
    name = "sellar_dis2"
    inputs = ("z", "y1")
    outputs = ("y2",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"z": 2}

    def compute(self, inputs):
        # as OpenMDAO: a negative y1 (only while the loop converges) is taken by its magnitude
        return {"y2": np.sqrt(np.abs(inputs["y1"])) + inputs["z"][:, 0] + inputs["z"][:, 1]}

    def compute_partials(self, inputs):
        y1 = inputs["y1"]
        n = len(y1)
        return {("y2", "z"): np.ones((n, 1, 2)),
                ("y2", "y1"): 0.5 * np.sign(y1) / np.sqrt(np.abs(y1))}


class SellarFunctions:
    """Objective and the two constraints, as one vector output ``con``."""

    name = "sellar_functions"
    inputs = ("x", "z", "y1", "y2")
    outputs = ("obj", "con")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"z": 2, "con": 2}

    def compute(self, inputs):
        y1, y2 = inputs["y1"], inputs["y2"]
        return {"obj": inputs["x"] ** 2 + inputs["z"][:, 1] + y1 + np.exp(-y2),
                "con": np.stack([3.16 - y1, y2 - 24.0], axis=1)}

    def compute_partials(self, inputs):
        y2 = inputs["y2"]
        n = len(y2)
        dcon_dy1 = np.zeros((n, 2, 1))
        dcon_dy1[:, 0, 0] = -1.0
        dcon_dy2 = np.zeros((n, 2, 1))
        dcon_dy2[:, 1, 0] = 1.0
        return {("obj", "x"): 2.0 * inputs["x"], ("obj", "z"): np.tile([[[0.0, 1.0]]], (n, 1, 1)),
                ("obj", "y1"): np.ones(n), ("obj", "y2"): -np.exp(-y2),
                ("con", "y1"): dcon_dy1, ("con", "y2"): dcon_dy2}
