"""Sobieski's supersonic business jet (SSBJ) as a user writes it for bev_mdo: four plain classes.

Sources
-------
- J. Sobieszczanski-Sobieski, J. S. Agte, R. R. Sandusky Jr., "Bi-Level Integrated System
  Synthesis (BLISS)", NASA/TM-1998-208715 (1998); also AIAA Journal 38(1):164-172 (2000).
  The problem: four disciplines (structure, aerodynamics, propulsion, range), ten design
  variables, maximise the Breguet range; the disciplines are analytic formulas and the
  "polynomial function" surrogates of Appendix A of the TM.
- J. Sobieszczanski-Sobieski, T. D. Altus, M. Phillips, R. Sandusky, "Bilevel Integrated
  System Synthesis for Concurrent and Distributed Processing", AIAA Journal 41(10), 2003
  (BLISS 2000), which uses the same SSBJ test case.
- GEMSEO (IRT Saint Exupery, LGPL-3.0), ``gemseo.problems.mdo.sobieski``: a Python port of the
  original code. Its source was read to pin down the constants the papers print only in part
  (the 5x5 cross-term matrix of the polynomial functions, the engine-deck fits, the reference
  values the polynomial inputs are normalised by) and GEMSEO 6.3.3 itself was run to
  cross-check the values of this implementation (test/mdo/test_ssbj.py holds the numbers).
  This file is an independent, batched (N points at once) rewrite; no GEMSEO code is used.

Reference optimum (the BLISS result, as GEMSEO documents it: ``SobieskiProblem.optimum_design``
and ``optimum_range``): range y_4 = 3963.98 nmi at

    x_shared = (t/c, altitude ft, Mach, aspect ratio, sweep deg, wing area ft^2)
             = (0.06, 60000, 1.4, 2.5, 70, 1500)
    x_1 = (taper ratio, wingbox x-section) = (0.38757, 0.75),  x_2 = Cf = 0.75,  x_3 = throttle = 0.15624

Variables (names as in the BLISS papers and GEMSEO; y_ij goes from discipline i to j; 1 structure,
2 aerodynamics, 3 propulsion, 4 mission):

    structure     x_shared, x_1, y_21 (lift), y_31 (engine weight)
                  -> y_12 = (total weight, wing twist), y_14 = (total weight, fuel weight), g_1 (7)
    aerodynamics  x_shared, x_2, y_12, y_32 (engine scale factor)
                  -> y_21 (lift), y_23 (drag), y_24 (lift/drag), g_2
    propulsion    x_shared, x_3, y_23
                  -> y_31 (engine weight), y_32 (engine scale factor), y_34 (SFC), g_3 (4)
    mission       x_shared, y_14, y_24, y_34 -> y_4 (range, nmi)

Structure, aerodynamics and propulsion form one loop (y_12, y_21, y_23, y_31, y_32); the
mission takes the converged values. Constraints, all g <= 0 (GEMSEO's "distance to the
threshold" form of the BLISS constraints):

    g_1 = (stress_1..5 - 1.09, twist - 1.04, 0.8 - twist)
    g_2 = pressure gradient - 1.04
    g_3 = (ESF - 1.5, 0.5 - ESF, throttle / throttle_upper - 1, temperature - 1.02)

Every value is a float64 array of a batch of N points: (N,) for a scalar, (N, k) for a vector
declared in ``shapes``. The configs next to this file (``ssbj_mdf.yaml``, ``ssbj_idf.yaml``) name
the classes as ``ssbj_disciplines:Structure`` (found relative to the config's folder).
"""
from __future__ import annotations

import numpy as np

REFERENCE_RANGE_NMI = 3963.98
REFERENCE_DESIGN = {
    "x_shared": (0.06, 60000.0, 1.4, 2.5, 70.0, 1500.0),
    "x_1": (0.38757, 0.75),
    "x_2": 0.75,
    "x_3": 0.15624,
}
# The design at which the polynomial functions are centred (BLISS's initial design; also the
# configs' start point): x_1, x_2, x_3, x_shared.
INITIAL_DESIGN = {
    "x_shared": (0.05, 45000.0, 1.6, 5.5, 55.0, 1000.0),
    "x_1": (0.25, 1.0),
    "x_2": 1.0,
    "x_3": 0.5,
}

MIN_FUEL_WEIGHT = 2000.0        # c_0, lb
MISC_WEIGHT = 25000.0           # c_1, lb
MAX_LOAD_FACTOR = 6.0           # c_2
REF_ENGINE_WEIGHT = 4360.0      # c_3, lb
MIN_DRAG_COEFFICIENT = 0.01375  # c_4
DEG = np.pi / 180.0

STRESS_LIMIT, TWIST_UPPER, TWIST_LOWER = 1.09, 1.04, 0.8
PGRAD_LIMIT = 1.04
ESF_UPPER, ESF_LOWER, TEMPERATURE_LIMIT = 1.5, 0.5, 1.02

# Cross terms of the polynomial functions: a_ij = a_ii * CROSS[i, j] (i < j), symmetric.
CROSS = np.array([
    [0.2736, 0.3970, 0.8152, 0.9230, 0.1108],
    [0.4252, 0.4415, 0.6357, 0.7435, 0.1138],
    [0.0329, 0.8856, 0.8390, 0.3657, 0.0019],
    [0.0878, 0.7248, 0.1978, 0.0200, 0.0169],
    [0.8955, 0.4568, 0.8075, 0.9239, 0.2525],
])
# Per functional relationship ("flag") of the BLISS polynomial function, the linear and the
# quadratic coefficient times the slope bound S (a_i * S, a_ii * S^2): 1 linear increasing,
# 2 nonlinear increasing, 3 linear decreasing, 4 nonlinear decreasing, 5 parabolic.
_LINEAR = {1: 0.05, 2: 0.075, 3: -0.05, 4: -0.075, 5: 0.0}
_QUADRATIC = {1: 0.0, 2: 0.025, 3: 0.0, 4: -0.025, 5: 0.0025}

# Values the polynomial inputs are normalised by (their values at INITIAL_DESIGN; the lift, the
# twist and the engine scale factor by 1, as in the original code).
_HALF_SPAN_0 = 0.5 * np.sqrt(5.5 * 1000.0)
_AERO_CENTER_0 = (1.0 + 2.0 * 0.25) / (3.0 * (1.0 + 0.25))


def polynomial_function(s, s_ref, flags, bounds):
    """The BLISS polynomial function (NASA/TM-1998-208715, Appendix A) of a batch.

    ``s`` (N, k) inputs, ``s_ref`` (k,) their reference values, ``flags`` (k,) their relationship,
    ``bounds`` (k,) the slope bounds S. The normalised input is clip(s / s_ref, 0.75, 1.25) - 1;
    the function is 1 + sum a_i s_i + 1/2 sum_ij a_ij s_i s_j, equal to 1 at s = s_ref.
    """
    s = np.atleast_2d(np.asarray(s, dtype=float))
    k = s.shape[1]
    x = np.clip(s / np.asarray(s_ref, dtype=float), 0.75, 1.25) - 1.0
    bounds = np.broadcast_to(np.asarray(bounds, dtype=float), (k,))
    a = np.array([_LINEAR[f] / b for f, b in zip(flags, bounds)])
    diag = np.array([_QUADRATIC[f] / b ** 2 for f, b in zip(flags, bounds)])
    A = np.diag(diag)
    for i in range(k):
        for j in range(i + 1, k):
            A[i, j] = A[j, i] = diag[i] * CROSS[i, j]
    return 1.0 + x @ a + 0.5 * np.einsum("ni,ij,nj->n", x, A, x)


def _split_shared(x_shared):
    return tuple(x_shared[:, i] for i in range(6))  # t/c, h, M, AR, sweep, Sref


def atmosphere(altitude_ft, mach):
    """(density slug/ft^3, speed ft/s) of the original code: a standard atmosphere fit."""
    low = altitude_ft < 36089.0
    ratio = np.where(low, 1.0 - 6.875e-6 * altitude_ft, 1.0)
    speed = np.where(low, mach * 1116.39 * np.sqrt(ratio), mach * 968.1)
    rho = np.where(low, 2.377e-3 * ratio ** 4.2561,
                   2.377e-3 * 0.2971 * np.exp((36089.0 - np.maximum(altitude_ft, 36089.0)) / 20806.7))
    return rho, speed


class Structure:
    """Discipline 1: weights, wing twist and the wing stress constraints."""

    name = "structure"
    inputs = ("x_shared", "x_1", "y_21", "y_31")
    outputs = ("y_12", "y_14", "g_1")
    shapes = {"x_shared": 6, "x_1": 2, "y_12": 2, "y_14": 2, "g_1": 7}

    def compute(self, inputs):
        tc, _, _, ar, sweep, sref = _split_shared(inputs["x_shared"])
        taper, wingbox = inputs["x_1"][:, 0], inputs["x_1"][:, 1]
        lift, engine_weight = inputs["y_21"], inputs["y_31"]
        half_span = 0.5 * np.sqrt(ar * sref)
        aero_center = (1.0 + 2.0 * taper) / (3.0 * (1.0 + taper))
        twist = polynomial_function(np.column_stack([wingbox, half_span, aero_center, lift]),
                                    [1.0, _HALF_SPAN_0, _AERO_CENTER_0, 1.0], [2, 4, 4, 3], 0.25)
        wing_weight = (0.0051 * (lift * MAX_LOAD_FACTOR) ** 0.557 * sref ** 0.649 * ar ** 0.5 * tc ** -0.4
                       * (1.0 + taper) ** 0.1 / np.cos(sweep * DEG) * (0.1875 * sref) ** 0.1
                       * polynomial_function(wingbox[:, None], [1.0], [1], [0.008]))
        thickness = tc * sref / np.sqrt(ar * sref)
        fuel_weight = MIN_FUEL_WEIGHT + (5.0 * sref / 18.0) * (2.0 / 3.0 * thickness) * 42.5
        total_weight = MISC_WEIGHT + wing_weight + fuel_weight + engine_weight
        s = np.column_stack([tc, lift, wingbox, half_span, aero_center])
        stress = [polynomial_function(s, [0.05, 1.0, 1.0, _HALF_SPAN_0, _AERO_CENTER_0], [4, 1, 4, 1, 1],
                                      0.1 + 0.05 * i) for i in range(5)]
        g_1 = np.column_stack([*(st - STRESS_LIMIT for st in stress), twist - TWIST_UPPER, TWIST_LOWER - twist])
        return {"y_12": np.column_stack([total_weight, twist]),
                "y_14": np.column_stack([total_weight, fuel_weight]),
                "g_1": g_1}


class Aerodynamics:
    """Discipline 2: lift, drag, lift/drag and the pressure-gradient constraint."""

    name = "aerodynamics"
    inputs = ("x_shared", "x_2", "y_12", "y_32")
    outputs = ("y_21", "y_23", "y_24", "g_2")
    shapes = {"x_shared": 6, "y_12": 2}

    def compute(self, inputs):
        tc, h, mach, _, sweep, sref = _split_shared(inputs["x_shared"])
        total_weight, twist = inputs["y_12"][:, 0], inputs["y_12"][:, 1]
        esf, cf = inputs["y_32"], inputs["x_2"]
        rho, speed = atmosphere(h, mach)
        dynamic_force = 0.5 * rho * speed ** 2 * sref
        cl = total_weight / dynamic_force
        fo1 = polynomial_function(np.column_stack([esf, cf]), [1.0, 1.0], [1, 1], 0.25)
        fo2 = polynomial_function(twist[:, None], [1.0], [5], [0.25])
        cd_min = MIN_DRAG_COEFFICIENT * fo1 + 3.05 * tc ** (5.0 / 3.0) * np.cos(sweep * DEG) ** 1.5
        # as in the original code, the sweep enters sqrt(sweep^2 - 1) in degrees
        k_induced = (mach ** 2 - 1.0) * np.cos(sweep * DEG) / (4.0 * np.sqrt(sweep ** 2 - 1.0) - 2.0)
        cd = fo2 * (cd_min + k_induced * cl ** 2)
        pgrad = polynomial_function(tc[:, None], [0.05], [1], [0.25])
        return {"y_21": total_weight.copy(), "y_23": dynamic_force * cd, "y_24": cl / cd,
                "g_2": pgrad - PGRAD_LIMIT}


SFC_COEFF = (1.13238425638512, 1.53436586044561, -0.00003295564466, -0.00016378694115, -0.31623315541888,
             0.00000410691343, -0.00005248000590, -0.00000000008574, 0.00000000190214, 0.00000001059951)
THROTTLE_UPPER_COEFF = (11483.7822254806, 10856.2163466548, -0.5080237941, 3200.157926969, -0.1466251679,
                        0.0000068572)
THROTTLE_SCALE = 16168.6  # lb of thrust per unit of x_3


class Propulsion:
    """Discipline 3: specific fuel consumption, engine scale factor and weight, engine constraints."""

    name = "propulsion"
    inputs = ("x_shared", "x_3", "y_23")
    outputs = ("y_31", "y_32", "y_34", "g_3")
    shapes = {"x_shared": 6, "g_3": 4}

    def compute(self, inputs):
        _, h, mach, _, _, _ = _split_shared(inputs["x_shared"])
        throttle, drag = inputs["x_3"], inputs["y_23"]
        thrust = throttle * THROTTLE_SCALE
        c = SFC_COEFF
        sfc = (c[0] + c[1] * mach + c[2] * h + c[3] * thrust + c[4] * mach ** 2 + 2 * h * mach * c[5]
               + 2 * thrust * mach * c[6] + c[7] * h ** 2 + 2 * thrust * h * c[8] + c[9] * thrust ** 2)
        esf = drag / (3.0 * thrust)
        engine_weight = 3.0 * REF_ENGINE_WEIGHT * esf ** 1.05
        t = THROTTLE_UPPER_COEFF
        thrust_upper = t[0] + t[1] * mach + t[2] * h + t[3] * mach ** 2 + 2 * t[4] * mach * h + t[5] * h ** 2
        temperature = polynomial_function(np.column_stack([mach, h, throttle]), [1.6, 45000.0, 0.5], [2, 4, 2], 0.25)
        g_3 = np.column_stack([esf - ESF_UPPER, ESF_LOWER - esf, thrust / thrust_upper - 1.0,
                               temperature - TEMPERATURE_LIMIT])
        return {"y_31": engine_weight, "y_32": esf, "y_34": sfc, "g_3": g_3}


class Mission:
    """Discipline 4: the Breguet range (nmi)."""

    name = "mission"
    inputs = ("x_shared", "y_14", "y_24", "y_34")
    outputs = ("y_4",)
    shapes = {"x_shared": 6, "y_14": 2}

    def compute(self, inputs):
        _, h, mach, _, _, _ = _split_shared(inputs["x_shared"])
        total_weight, fuel_weight = inputs["y_14"][:, 0], inputs["y_14"][:, 1]
        sqrt_theta = np.where(h < 36089.0, np.sqrt(np.abs(1.0 - 6.875e-6 * h)), np.sqrt(0.7519))
        with np.errstate(invalid="ignore", divide="ignore"):  # W_t <= W_f: NaN, a failed point
            log_ratio = np.log(total_weight / (total_weight - fuel_weight))
        return {"y_4": mach * inputs["y_24"] * 661.0 * sqrt_theta / inputs["y_34"] * log_ratio}
