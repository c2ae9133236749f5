"""Golinski's speed reducer as a three-discipline MDO problem with vector variables.

Source: J. Golinski, "Optimal synthesis problems solved by means of nonlinear programming and
random methods", J. Mechanisms 5 (1970) 287-309; posed as an MDO test problem (gear + two shaft
subsystems sharing the gear variables) in S. L. Padula, N. Alexandrov, L. L. Green, "MDO test suite
at NASA Langley Research Center", AIAA 96-4028 (1996), and in S. Kodiyalam, "Evaluation of methods
for multidisciplinary design optimization (MDO), Phase I", NASA CR-1998-208716.

Variables: x_shared = (b face width, m tooth module, z pinion teeth) shared by all three
disciplines; x_shaft1 = (l1, d1) and x_shaft2 = (l2, d2) the length between bearings and the
diameter of each shaft. Minimise the weight (volume x density)

    W = 0.7854 b m^2 (3.3333 z^2 + 14.9334 z - 43.0934)                 gear
        - 1.508 b d1^2 + 7.4777 d1^3 + 0.7854 l1 d1^2                    shaft 1
        - 1.508 b d2^2 + 7.4777 d2^3 + 0.7854 l2 d2^2                    shaft 2

subject to 11 normalised constraints g <= 0 (gear bending and contact stress, size limits;
shaft deflection, stress and length/diameter ratio), here three vector outputs g_gear (5),
g_shaft1 (3), g_shaft2 (3), and the bounds 2.6 <= b <= 3.6, 0.7 <= m <= 0.8, 17 <= z <= 28,
7.3 <= l1, l2 <= 8.3, 2.9 <= d1 <= 3.9, 5.0 <= d2 <= 5.5 (z is treated as continuous, as in the
references).

Reference optimum (Kodiyalam 1998; also Ray 2003, "Golinski's speed reducer problem revisited",
AIAA J. 41(3)): W = 2994.47 at x = (3.5, 0.7, 17, 7.3, 7.71532, 3.35021, 5.28665), with the
m and z lower bounds, l1's lower bound, the gear's face-width ratio (g_gear[3]: b = 5 m) and the shaft
stress and shaft-2 ratio constraints active.

The three disciplines are coupled only through the shared variables and the weight sum (no
feedback loop), so this problem exercises vector design variables, vector constraint outputs and
analytic partials of every discipline (the gradient is one analysis). config: examples/golinski.yaml.
"""
from __future__ import annotations

import numpy as np

REFERENCE = {"weight": 2994.47, "x_shared": (3.5, 0.7, 17.0), "x_shaft1": (7.3, 3.35021),
             "x_shaft2": (7.71532, 5.28665)}


class Gear:
    name = "gear"
    inputs = ("x_shared",)
    outputs = ("w_gear", "g_gear")
    # a vector holds one unit: x_shared mixes cm and a tooth count, so the problem is declared in numbers
    units = dict.fromkeys(inputs + outputs, "1")
    shapes = {"x_shared": 3, "g_gear": 5}

    def compute(self, inputs):
        b, m, z = inputs["x_shared"].T
        w = 0.7854 * b * m**2 * (3.3333 * z**2 + 14.9334 * z - 43.0934)
        g = np.stack([27.0 / (b * m**2 * z) - 1.0,          # bending stress of the teeth
                      397.5 / (b * m**2 * z**2) - 1.0,      # contact stress of the teeth
                      m * z / 40.0 - 1.0,                   # size (pitch diameter)
                      5.0 * m / b - 1.0,                    # face width / module >= 5
                      b / (12.0 * m) - 1.0], axis=1)        # face width / module <= 12
        return {"w_gear": w, "g_gear": g}

    def compute_partials(self, inputs):
        b, m, z = inputs["x_shared"].T
        n = len(b)
        p = 3.3333 * z**2 + 14.9334 * z - 43.0934
        dw = np.stack([0.7854 * m**2 * p, 1.5708 * b * m * p, 0.7854 * b * m**2 * (6.6666 * z + 14.9334)], axis=1)
        dg = np.zeros((n, 5, 3))
        dg[:, 0] = np.stack([-27.0 / (b**2 * m**2 * z), -54.0 / (b * m**3 * z), -27.0 / (b * m**2 * z**2)], axis=1)
        dg[:, 1] = np.stack([-397.5 / (b**2 * m**2 * z**2), -795.0 / (b * m**3 * z**2),
                             -795.0 / (b * m**2 * z**3)], axis=1)
        dg[:, 2, 1], dg[:, 2, 2] = z / 40.0, m / 40.0
        dg[:, 3, 0], dg[:, 3, 1] = -5.0 * m / b**2, 5.0 / b
        dg[:, 4, 0], dg[:, 4, 1] = 1.0 / (12.0 * m), -b / (12.0 * m**2)
        return {("w_gear", "x_shared"): dw[:, None, :], ("g_gear", "x_shared"): dg}


class Shaft:
    """Shaft 1 or 2 (option ``shaft``): weight and (deflection, stress, length/diameter) constraints."""

    _CONST = {1: (16.9e6, 110.0, 1.5), 2: (157.5e6, 85.0, 1.1)}  # torque term, allowed stress, ratio

    def __init__(self, shaft: int = 1):
        if shaft not in self._CONST:
            raise ValueError(f"shaft must be 1 or 2, got {shaft!r}")
        self.k, self.s, self.a = self._CONST[shaft]
        self.x, self.w, self.g = f"x_shaft{shaft}", f"w_shaft{shaft}", f"g_shaft{shaft}"
        self.name = f"shaft{shaft}"
        self.inputs = ("x_shared", self.x)
        self.outputs = (self.w, self.g)
        self.shapes = {"x_shared": 3, self.x: 2, self.g: 3}
        self.units = dict.fromkeys(self.inputs + self.outputs, "1")  # as Gear's

    def _terms(self, inputs):
        b, m, z = inputs["x_shared"].T
        length, d = inputs[self.x].T
        q = 745.0 * length / (m * z)
        r = np.sqrt(q**2 + self.k)
        return b, m, z, length, d, q, r

    def compute(self, inputs):
        b, m, z, length, d, q, r = self._terms(inputs)
        w = -1.508 * b * d**2 + 7.4777 * d**3 + 0.7854 * length * d**2
        g = np.stack([1.93 * length**3 / (m * z * d**4) - 1.0,   # transverse deflection
                      r / (self.s * d**3) - 1.0,                 # stress
                      (self.a * d + 1.9) / length - 1.0], axis=1)  # length / diameter
        return {self.w: w, self.g: g}

    def compute_partials(self, inputs):
        b, m, z, length, d, q, r = self._terms(inputs)
        n = len(b)
        dw_shared = np.stack([-1.508 * d**2, np.zeros(n), np.zeros(n)], axis=1)
        dw_shaft = np.stack([0.7854 * d**2, -3.016 * b * d + 22.4331 * d**2 + 1.5708 * length * d], axis=1)
        defl = 1.93 * length**3 / (m * z * d**4)
        dg_shared, dg_shaft = np.zeros((n, 3, 3)), np.zeros((n, 3, 2))
        dg_shared[:, 0, 1], dg_shared[:, 0, 2] = -defl / m, -defl / z
        dg_shaft[:, 0, 0], dg_shaft[:, 0, 1] = 3.0 * defl / length, -4.0 * defl / d
        dr_dq = q / r / (self.s * d**3)
        dg_shared[:, 1, 1], dg_shared[:, 1, 2] = -dr_dq * q / m, -dr_dq * q / z
        dg_shaft[:, 1, 0], dg_shaft[:, 1, 1] = dr_dq * q / length, -3.0 * r / (self.s * d**4)
        dg_shaft[:, 2, 0], dg_shaft[:, 2, 1] = -(self.a * d + 1.9) / length**2, self.a / length
        return {(self.w, "x_shared"): dw_shared[:, None, :], (self.w, self.x): dw_shaft[:, None, :],
                (self.g, "x_shared"): dg_shared, (self.g, self.x): dg_shaft}


class Weight:
    name = "weight"
    inputs = ("w_gear", "w_shaft1", "w_shaft2")
    outputs = ("weight",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"weight": inputs["w_gear"] + inputs["w_shaft1"] + inputs["w_shaft2"]}

    def compute_partials(self, inputs):
        one = np.ones(len(inputs["w_gear"]))
        return {("weight", k): one for k in self.inputs}
