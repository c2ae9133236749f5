"""The Sellar problem as a user writes it for bev_mdo: three plain classes, no bev_mdo import.

Source: R. S. Sellar, S. M. Batill, J. E. Renaud, "Response surface based, concurrent subspace
optimization for multidisciplinary system design", AIAA 96-0714 (1996); the form and reference
optimum are OpenMDAO's (openmdao.test_suite.components.sellar, "Sellar problem" docs):

    min   f = x^2 + z2 + y1 + exp(-y2)
    s.t.  y1 >= 3.16,  y2 <= 24,   -10 <= z1 <= 10,  0 <= z2 <= 10,  0 <= x <= 10
    y1 = z1^2 + z2 + x - 0.2 y2          (discipline 1)
    y2 = sqrt(y1) + z1 + z2              (discipline 2; a loop y1 <-> y2)

Reference optimum: f = 3.18339395 at z = (1.977639, 0), x = 0 (y1 = 3.16 active).

Every value is a float64 array of shape (N,): a batch of N design points, computed at once.
Each class also gives its analytic partial derivatives (``compute_partials``, docs/derivatives.md;
``bev-mdo check-partials examples/sellar/sellar_mdf.yaml`` compares them with finite differences),
which the MDF/IDF gradients and the Newton MDA (``sellar_mdf_newton.yaml``) use.
``sellar_mdf.yaml`` / ``sellar_idf.yaml`` next to this file name the classes as
``sellar_disciplines:SellarDis1``: a module is found relative to the config's folder (then the
working directory), on both transports.
"""
from __future__ import annotations

import numpy as np

REFERENCE_OPTIMUM = {"z1": 1.977639, "z2": 0.0, "x": 0.0}
REFERENCE_OBJECTIVE = 3.18339395


class SellarDis1:
    name = "sellar1"
    inputs = ("z1", "z2", "x", "y2")
    outputs = ("y1",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"y1": inputs["z1"] ** 2 + inputs["z2"] + inputs["x"] - 0.2 * inputs["y2"]}

    def compute_partials(self, inputs):
        n = len(inputs["z1"])
        return {("y1", "z1"): 2.0 * inputs["z1"], ("y1", "z2"): np.ones(n), ("y1", "x"): np.ones(n),
                ("y1", "y2"): np.full(n, -0.2)}


class SellarDis2:
    name = "sellar2"
    inputs = ("z1", "z2", "y1")
    outputs = ("y2",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        # |y1|: OpenMDAO's Sellar does the same, so an MDA iterate with y1 < 0 stays defined
        return {"y2": np.sqrt(np.abs(inputs["y1"])) + inputs["z1"] + inputs["z2"]}

    def compute_partials(self, inputs):
        y1 = inputs["y1"]
        n = len(y1)
        # d sqrt|y1| / d y1 = sign(y1) / (2 sqrt|y1|); y1 = 0 (a cusp) gets a large finite slope
        return {("y2", "y1"): np.sign(y1) * 0.5 / np.sqrt(np.maximum(np.abs(y1), 1e-300)),
                ("y2", "z1"): np.ones(n), ("y2", "z2"): np.ones(n)}


class SellarObjective:
    name = "sellar_obj"
    inputs = ("x", "z2", "y1", "y2")
    outputs = ("obj",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"obj": inputs["x"] ** 2 + inputs["z2"] + inputs["y1"] + np.exp(-inputs["y2"])}

    def compute_partials(self, inputs):
        n = len(inputs["x"])
        return {("obj", "x"): 2.0 * inputs["x"], ("obj", "z2"): np.ones(n), ("obj", "y1"): np.ones(n),
                ("obj", "y2"): -np.exp(-inputs["y2"])}
