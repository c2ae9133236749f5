"""The propane combustion problem as a user writes it for bev_mdo: four plain classes.

Source: the NASA MDO test suite (S. L. Padula, N. Alexandrov, L. L. Green, "MDO test suite at NASA
Langley Research Center", AIAA 96-4028, 1996) and R. P. Tedford, J. R. R. A. Martins, "On the common
structure of MDO problems: a comparison of architectures", AIAA 2006-7080, in the decoupled form of
GEMSEO (IRT Saint Exupery), ``gemseo.problems.mdo.propane`` (C. Vanaret; LGPL-3.0). The equations
were re-typed from GEMSEO's code; no GEMSEO code is used.

The chemical equilibrium of propane burnt in air: x_shared = (x1, x3, x6, x7) of the paper's eleven
mole numbers are the design; the three "combustion" disciplines give the others in closed form
(GEMSEO's decoupled form: each depends on x_shared only, so the graph is feed-forward), with
D = 400 x1^2 - 2403 x1 + 3600 and T = x6 + x7 - 2 x3 + 94:

    comb1 -> y_1 = (-x1 (x6 + x7 - 8) / 6,  3 - x1)
    comb2 -> y_2 = ((x1 - 3)(x6 + x7 - 8) / 6,  -(x1 - 3) x1 T / (2 D))
    comb3 -> y_3 = (40 - 2 x3,  x1^2 T / (2 D),  200 (x1 - 3)^2 T / D)

and the reaction discipline the four residuals of the equilibrium (in GEMSEO's indexing of y):

    F2 = 2 x1 + y_1[0] + y_1[1] + x7 + y_2[1] + y_3[0] + 2 y_3[1] - 10
    F6 = sqrt(y_1[0] y_1[1]) - sqrt(40 x1 / y_3[2]) x6
    F7 = sqrt(x1 y_1[0]) - sqrt(40 y_1[1] / y_3[2]) x7
    F9 = x1 sqrt(x3) - y_1[1] y_3[0] sqrt(40 / y_3[2])

    minimise obj = F2 + F6 + F7 + F9   subject to F2, F6, F7, F9 >= 0,   x_shared in [0.001, (2, 30, 2, 2)]

so the minimum is 0 where all four residuals vanish (the equilibrium). **Sign trap**: as in GEMSEO,
the outputs ``f_2, f_6, f_7, f_9`` are the residuals NEGATED (-F2, ...), so the constraints are
``f_i <= 0`` (``{upper: 0}``), while ``obj`` sums the residuals themselves. (y_2[0] is computed but
not used by the reaction, as in GEMSEO.)

Optimum (GEMSEO's documentation): x_shared = (1.378887, 18.426810, 1.094798, 0.931214), obj = 0,
every constraint active. OPTIMUM below is that point solved to machine precision (all four
residuals zero: 4 equations in 4 unknowns; docs/propane.md).
"""
from __future__ import annotations

import numpy as np

# the four residuals vanish here to 3e-15 (scipy.optimize.fsolve from GEMSEO's published point)
OPTIMUM = (1.378886808657918, 18.42681018787352, 1.0947980052447164, 0.931213523916351)


def _d(x1):
    return 400.0 * x1 ** 2 - 2403.0 * x1 + 3600.0, 800.0 * x1 - 2403.0  # D and dD/dx1


def _t(x):
    return x[:, 2] + x[:, 3] - 2.0 * x[:, 1] + 94.0  # T


def _rows(n, *cols):
    """(N, 1, k) partial of one output element w.r.t. a k-vector, from k columns (arrays or numbers)."""
    return np.stack([np.broadcast_to(np.asarray(c, dtype=float), (n,)) for c in cols], axis=1)[:, None, :]


class PropaneComb1:
    name = "comb1"
    inputs = ("x_shared",)
    outputs = ("y_1",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"x_shared": 4, "y_1": 2}

    def compute(self, inputs):
        x = inputs["x_shared"]
        return {"y_1": np.column_stack([-x[:, 0] * (x[:, 2] + x[:, 3] - 8.0) / 6.0, 3.0 - x[:, 0]])}

    def compute_partials(self, inputs):
        x = inputs["x_shared"]
        n = len(x)
        return {("y_1", "x_shared"): np.concatenate([
            _rows(n, -(x[:, 2] + x[:, 3] - 8.0) / 6.0, 0.0, -x[:, 0] / 6.0, -x[:, 0] / 6.0),
            _rows(n, -1.0, 0.0, 0.0, 0.0)], axis=1)}


class PropaneComb2:
    name = "comb2"
    inputs = ("x_shared",)
    outputs = ("y_2",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"x_shared": 4, "y_2": 2}

    def compute(self, inputs):
        x = inputs["x_shared"]
        x1 = x[:, 0]
        d, _ = _d(x1)
        return {"y_2": np.column_stack([(x1 - 3.0) * (x[:, 2] + x[:, 3] - 8.0) / 6.0,
                                        -(x1 - 3.0) * x1 * _t(x) / (2.0 * d)])}

    def compute_partials(self, inputs):
        x = inputs["x_shared"]
        n, x1, t = len(x), x[:, 0], _t(x)
        d, dd = _d(x1)
        g = -(x1 ** 2 - 3.0 * x1) / (2.0 * d)
        dg = -((2.0 * x1 - 3.0) * d - (x1 ** 2 - 3.0 * x1) * dd) / (2.0 * d ** 2)
        return {("y_2", "x_shared"): np.concatenate([
            _rows(n, (x[:, 2] + x[:, 3] - 8.0) / 6.0, 0.0, (x1 - 3.0) / 6.0, (x1 - 3.0) / 6.0),
            _rows(n, dg * t, -2.0 * g, g, g)], axis=1)}


class PropaneComb3:
    name = "comb3"
    inputs = ("x_shared",)
    outputs = ("y_3",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"x_shared": 4, "y_3": 3}

    def compute(self, inputs):
        x = inputs["x_shared"]
        x1, t = x[:, 0], _t(x)
        d, _ = _d(x1)
        return {"y_3": np.column_stack([40.0 - 2.0 * x[:, 1], x1 ** 2 * t / (2.0 * d),
                                        200.0 * (x1 - 3.0) ** 2 * t / d])}

    def compute_partials(self, inputs):
        x = inputs["x_shared"]
        n, x1, t = len(x), x[:, 0], _t(x)
        d, dd = _d(x1)
        h = x1 ** 2 / (2.0 * d)
        dh = (2.0 * x1 * d - x1 ** 2 * dd) / (2.0 * d ** 2)
        k = 200.0 * (x1 - 3.0) ** 2 / d
        dk = 200.0 * (2.0 * (x1 - 3.0) * d - (x1 - 3.0) ** 2 * dd) / d ** 2
        return {("y_3", "x_shared"): np.concatenate([
            _rows(n, 0.0, -2.0, 0.0, 0.0), _rows(n, dh * t, -2.0 * h, h, h), _rows(n, dk * t, -2.0 * k, k, k)],
            axis=1)}


class PropaneReaction:
    name = "reaction"
    inputs = ("x_shared", "y_1", "y_2", "y_3")
    outputs = ("f_2", "f_6", "f_7", "f_9", "obj")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    shapes = {"x_shared": 4, "y_1": 2, "y_2": 2, "y_3": 3}

    @staticmethod
    def _residuals(inputs):
        x, y1, y2, y3 = inputs["x_shared"], inputs["y_1"], inputs["y_2"], inputs["y_3"]
        f2 = 2.0 * x[:, 0] + y1[:, 0] + y1[:, 1] + x[:, 3] + y2[:, 1] + y3[:, 0] + 2.0 * y3[:, 1] - 10.0
        f6 = np.sqrt(y1[:, 0] * y1[:, 1]) - np.sqrt(40.0 * x[:, 0] / y3[:, 2]) * x[:, 2]
        f7 = np.sqrt(x[:, 0] * y1[:, 0]) - np.sqrt(40.0 * y1[:, 1] / y3[:, 2]) * x[:, 3]
        f9 = x[:, 0] * np.sqrt(x[:, 1]) - y1[:, 1] * y3[:, 0] * np.sqrt(40.0 / y3[:, 2])
        return f2, f6, f7, f9

    def compute(self, inputs):
        # a negative square-root argument (an IDF iterate off the equilibrium) gives NaN: the point fails
        with np.errstate(invalid="ignore"):
            f2, f6, f7, f9 = self._residuals(inputs)
        return {"f_2": -f2, "f_6": -f6, "f_7": -f7, "f_9": -f9, "obj": f2 + f6 + f7 + f9}

    def compute_partials(self, inputs):
        x, y1, y3 = inputs["x_shared"], inputs["y_1"], inputs["y_3"]
        n = len(x)
        x1, x3, x6, x7 = x.T
        a, b = y1[:, 0], y1[:, 1]
        e, c = y3[:, 0], y3[:, 2]
        with np.errstate(invalid="ignore", divide="ignore"):
            sab, s6, sxa, s7, s3, s9 = (np.sqrt(a * b), np.sqrt(40.0 * x1 / c), np.sqrt(x1 * a),
                                        np.sqrt(40.0 * b / c), np.sqrt(x3), np.sqrt(40.0 / c))
            F = {  # d F_i / d (x_shared, y_1, y_2, y_3), rows of 4, 2, 2, 3 columns
                2: (_rows(n, 2.0, 0.0, 0.0, 1.0), _rows(n, 1.0, 1.0), _rows(n, 0.0, 1.0), _rows(n, 1.0, 2.0, 0.0)),
                6: (_rows(n, -x6 * 20.0 / (c * s6), 0.0, -s6, 0.0), _rows(n, 0.5 * b / sab, 0.5 * a / sab),
                    _rows(n, 0.0, 0.0), _rows(n, 0.0, 0.0, x6 * 20.0 * x1 / (c ** 2 * s6))),
                7: (_rows(n, 0.5 * a / sxa, 0.0, 0.0, -s7), _rows(n, 0.5 * x1 / sxa, -x7 * 20.0 / (c * s7)),
                    _rows(n, 0.0, 0.0), _rows(n, 0.0, 0.0, x7 * 20.0 * b / (c ** 2 * s7))),
                9: (_rows(n, s3, 0.5 * x1 / s3, 0.0, 0.0), _rows(n, 0.0, -e * s9), _rows(n, 0.0, 0.0),
                    _rows(n, -b * s9, 0.0, b * e * 20.0 / (c ** 2 * s9))),
            }
        names = ("x_shared", "y_1", "y_2", "y_3")
        out = {}
        for i, rows in F.items():
            for name, r in zip(names, rows):
                out[(f"f_{i}", name)] = -r
        for j, name in enumerate(names):
            out[("obj", name)] = sum(F[i][j] for i in F)
        return out
