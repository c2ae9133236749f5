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
declared in ``shapes``. Every class also has ``compute_partials`` (analytic, batched:
{(output, input): (N, out_size, in_size)}; ``bev-mdo check-partials`` compares them with finite
differences); the polynomial functions clip their inputs, and the partials there are the
one-sided derivatives from inside the 0.75..1.25 band.

The configs next to this file (``ssbj_mdf.yaml``, ``ssbj_idf.yaml``) name
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


def _coefficients(flags, bounds, k: int):
    """(linear a (k,), quadratic A (k, k)) of the polynomial approximation for these slope flags and bounds."""
    bounds = np.broadcast_to(np.asarray(bounds, dtype=float), (k,))
    a = np.array([_LINEAR[f] / b for f, b in zip(flags, bounds)])
    diag = np.array([_QUADRATIC[f] / b ** 2 for f, b in zip(flags, bounds)])
    A = np.diag(diag)
    for i in range(k):
        for j in range(i + 1, k):
            A[i, j] = A[j, i] = diag[i] * CROSS[i, j]
    return a, A


def polynomial_function(s, s_ref, flags, bounds):
    """The BLISS polynomial function (NASA/TM-1998-208715, Appendix A) of a batch.

    ``s`` (N, k) inputs, ``s_ref`` (k,) their reference values, ``flags`` (k,) their relationship,
    ``bounds`` (k,) the slope bounds S. The normalised input is clip(s / s_ref, 0.75, 1.25) - 1;
    the function is 1 + sum a_i s_i + 1/2 sum_ij a_ij s_i s_j, equal to 1 at s = s_ref.
    """
    s = np.atleast_2d(np.asarray(s, dtype=float))
    k = s.shape[1]
    x = np.clip(s / np.asarray(s_ref, dtype=float), 0.75, 1.25) - 1.0
    a, A = _coefficients(flags, bounds, k)
    return 1.0 + x @ a + 0.5 * np.einsum("ni,ij,nj->n", x, A, x)


def polynomial_gradient(s, s_ref, flags, bounds):
    """(value (N,), d value / d s (N, k)) of :func:`polynomial_function`; the derivative is zero
    where an input is clipped (outside 0.75..1.25 of its reference value)."""
    s = np.atleast_2d(np.asarray(s, dtype=float))
    k = s.shape[1]
    s_ref = np.asarray(s_ref, dtype=float)
    ratio = s / s_ref
    x = np.clip(ratio, 0.75, 1.25) - 1.0
    a, A = _coefficients(flags, bounds, k)
    value = 1.0 + x @ a + 0.5 * np.einsum("ni,ij,nj->n", x, A, x)
    inside = (ratio >= 0.75) & (ratio <= 1.25)
    return value, (a + x @ A) * np.where(inside, 1.0 / s_ref, 0.0)


def _jac(n, rows, cols):
    return np.zeros((n, rows, cols))


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
    # one unit a variable: x_shared (t/c, ft, Mach, AR, deg, ft^2) and y_12 (lb, twist) mix units, so "1"
    units = {**dict.fromkeys(inputs + outputs, "1"), "y_21": "lb", "y_31": "lb", "y_14": "lb"}
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

    def compute_partials(self, inputs):
        tc, _, _, ar, sweep, sref = _split_shared(inputs["x_shared"])
        taper, wingbox = inputs["x_1"][:, 0], inputs["x_1"][:, 1]
        lift = inputs["y_21"]
        n = len(tc)
        half_span = 0.5 * np.sqrt(ar * sref)
        dspan_dar, dspan_dsref = half_span / (2.0 * ar), half_span / (2.0 * sref)
        aero_center = (1.0 + 2.0 * taper) / (3.0 * (1.0 + taper))
        dcenter_dtaper = 1.0 / (3.0 * (1.0 + taper) ** 2)
        _, gt = polynomial_gradient(np.column_stack([wingbox, half_span, aero_center, lift]),
                                    [1.0, _HALF_SPAN_0, _AERO_CENTER_0, 1.0], [2, 4, 4, 3], 0.25)
        # d twist / d (x_shared, x_1, y_21): rows of 6 + 2 + 1
        twist_xs, twist_x1 = np.zeros((n, 6)), np.zeros((n, 2))
        twist_xs[:, 3], twist_xs[:, 5] = gt[:, 1] * dspan_dar, gt[:, 1] * dspan_dsref
        twist_x1[:, 0], twist_x1[:, 1] = gt[:, 2] * dcenter_dtaper, gt[:, 0]
        twist_lift = gt[:, 3]
        p_w, gp_w = polynomial_gradient(wingbox[:, None], [1.0], [1], [0.008])
        coeff = (0.0051 * (lift * MAX_LOAD_FACTOR) ** 0.557 * sref ** 0.649 * ar ** 0.5 * tc ** -0.4
                 * (1.0 + taper) ** 0.1 / np.cos(sweep * DEG) * (0.1875 * sref) ** 0.1)
        wing_weight = coeff * p_w
        fuel_wing = (5.0 * sref / 18.0) * (2.0 / 3.0 * tc * sref / np.sqrt(ar * sref)) * 42.5
        fuel_xs = np.zeros((n, 6))
        fuel_xs[:, 0], fuel_xs[:, 3], fuel_xs[:, 5] = fuel_wing / tc, -0.5 * fuel_wing / ar, 1.5 * fuel_wing / sref
        wt_xs = fuel_xs.copy()
        wt_xs[:, 0] += -0.4 * wing_weight / tc
        wt_xs[:, 3] += 0.5 * wing_weight / ar
        wt_xs[:, 4] += wing_weight * np.tan(sweep * DEG) * DEG
        wt_xs[:, 5] += 0.749 * wing_weight / sref
        wt_x1 = np.column_stack([0.1 * wing_weight / (1.0 + taper), coeff * gp_w[:, 0]])
        wt_lift = 0.557 * wing_weight / lift
        s = np.column_stack([tc, lift, wingbox, half_span, aero_center])
        g1_xs, g1_x1, g1_lift = _jac(n, 7, 6), _jac(n, 7, 2), _jac(n, 7, 1)
        for i in range(5):
            _, gs = polynomial_gradient(s, [0.05, 1.0, 1.0, _HALF_SPAN_0, _AERO_CENTER_0], [4, 1, 4, 1, 1],
                                        0.1 + 0.05 * i)
            g1_xs[:, i, 0], g1_xs[:, i, 3], g1_xs[:, i, 5] = gs[:, 0], gs[:, 3] * dspan_dar, gs[:, 3] * dspan_dsref
            g1_x1[:, i, 0], g1_x1[:, i, 1] = gs[:, 4] * dcenter_dtaper, gs[:, 2]
            g1_lift[:, i, 0] = gs[:, 1]
        g1_xs[:, 5], g1_xs[:, 6] = twist_xs, -twist_xs
        g1_x1[:, 5], g1_x1[:, 6] = twist_x1, -twist_x1
        g1_lift[:, 5, 0], g1_lift[:, 6, 0] = twist_lift, -twist_lift
        y12_xs, y12_x1, y12_lift, y12_we = _jac(n, 2, 6), _jac(n, 2, 2), _jac(n, 2, 1), _jac(n, 2, 1)
        y12_xs[:, 0], y12_xs[:, 1] = wt_xs, twist_xs
        y12_x1[:, 0], y12_x1[:, 1] = wt_x1, twist_x1
        y12_lift[:, 0, 0], y12_lift[:, 1, 0] = wt_lift, twist_lift
        y12_we[:, 0, 0] = 1.0
        y14_xs, y14_x1, y14_lift, y14_we = _jac(n, 2, 6), _jac(n, 2, 2), _jac(n, 2, 1), _jac(n, 2, 1)
        y14_xs[:, 0], y14_xs[:, 1] = wt_xs, fuel_xs
        y14_x1[:, 0] = wt_x1
        y14_lift[:, 0, 0] = wt_lift
        y14_we[:, 0, 0] = 1.0
        return {("y_12", "x_shared"): y12_xs, ("y_12", "x_1"): y12_x1, ("y_12", "y_21"): y12_lift,
                ("y_12", "y_31"): y12_we, ("y_14", "x_shared"): y14_xs, ("y_14", "x_1"): y14_x1,
                ("y_14", "y_21"): y14_lift, ("y_14", "y_31"): y14_we,
                ("g_1", "x_shared"): g1_xs, ("g_1", "x_1"): g1_x1, ("g_1", "y_21"): g1_lift}


class Aerodynamics:
    """Discipline 2: lift, drag, lift/drag and the pressure-gradient constraint."""

    name = "aerodynamics"
    inputs = ("x_shared", "x_2", "y_12", "y_32")
    outputs = ("y_21", "y_23", "y_24", "g_2")
    units = {**dict.fromkeys(inputs + outputs, "1"), "y_21": "lb", "y_23": "lb"}
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

    def compute_partials(self, inputs):
        tc, h, mach, _, sweep, sref = _split_shared(inputs["x_shared"])
        total_weight, twist = inputs["y_12"][:, 0], inputs["y_12"][:, 1]
        esf, cf = inputs["y_32"], inputs["x_2"]
        n = len(tc)
        rho, speed = atmosphere(h, mach)
        low = h < 36089.0
        ratio = np.where(low, 1.0 - 6.875e-6 * h, 1.0)
        drho_dh = np.where(low, 2.377e-3 * 4.2561 * ratio ** 3.2561 * -6.875e-6, -rho / 20806.7)
        dspeed_dh = np.where(low, mach * 1116.39 * 0.5 / np.sqrt(ratio) * -6.875e-6, 0.0)
        dspeed_dmach = speed / mach
        q = 0.5 * rho * speed ** 2
        dq_dh = 0.5 * drho_dh * speed ** 2 + rho * speed * dspeed_dh
        dq_dmach = rho * speed * dspeed_dmach
        cl = total_weight / (q * sref)
        fo1, g_fo1 = polynomial_gradient(np.column_stack([esf, cf]), [1.0, 1.0], [1, 1], 0.25)
        fo2, g_fo2 = polynomial_gradient(twist[:, None], [1.0], [5], [0.25])
        cos = np.cos(sweep * DEG)
        cd_min = MIN_DRAG_COEFFICIENT * fo1 + 3.05 * tc ** (5.0 / 3.0) * cos ** 1.5
        den = 4.0 * np.sqrt(sweep ** 2 - 1.0) - 2.0
        k_induced = (mach ** 2 - 1.0) * cos / den
        base = cd_min + k_induced * cl ** 2
        cd = fo2 * base
        # derivatives of (cl, cd_min, k, fo2, q*sref) by the variables: t/c, h, M, sweep, Sref, Wt, twist, ESF, Cf
        names = ("tc", "h", "mach", "sweep", "sref", "wt", "twist", "esf", "cf")
        dcl = {"h": -cl / q * dq_dh, "mach": -cl / q * dq_dmach, "sref": -cl / sref, "wt": 1.0 / (q * sref)}
        dcdmin = {"tc": 3.05 * 5.0 / 3.0 * tc ** (2.0 / 3.0) * cos ** 1.5,
                  "sweep": -3.05 * tc ** (5.0 / 3.0) * 1.5 * np.sqrt(cos) * np.sin(sweep * DEG) * DEG,
                  "esf": MIN_DRAG_COEFFICIENT * g_fo1[:, 0], "cf": MIN_DRAG_COEFFICIENT * g_fo1[:, 1]}
        dk = {"mach": 2.0 * mach * cos / den,
              "sweep": (-(mach ** 2 - 1.0) * np.sin(sweep * DEG) * DEG * den
                        - (mach ** 2 - 1.0) * cos * 4.0 * sweep / np.sqrt(sweep ** 2 - 1.0)) / den ** 2}
        dforce = {"h": dq_dh * sref, "mach": dq_dmach * sref, "sref": q}
        zero = np.zeros(n)
        dcd, ddrag, dld = {}, {}, {}
        for v in names:
            dbase = dcdmin.get(v, zero) + dk.get(v, zero) * cl ** 2 + 2.0 * k_induced * cl * dcl.get(v, zero)
            dcd[v] = (g_fo2[:, 0] if v == "twist" else zero) * base + fo2 * dbase
            ddrag[v] = dforce.get(v, zero) * cd + q * sref * dcd[v]
            dld[v] = dcl.get(v, zero) / cd - cl * dcd[v] / cd ** 2
        shared = {"tc": 0, "h": 1, "mach": 2, "sweep": 4, "sref": 5}
        out = {}
        for name, d in (("y_23", ddrag), ("y_24", dld)):
            xs = np.zeros((n, 1, 6))
            for v, j in shared.items():
                xs[:, 0, j] = d[v]
            out[(name, "x_shared")] = xs
            out[(name, "y_12")] = np.stack([d["wt"], d["twist"]], axis=1)[:, None, :]
            out[(name, "y_32")] = d["esf"]
            out[(name, "x_2")] = d["cf"]
        out[("y_21", "y_12")] = np.tile([[[1.0, 0.0]]], (n, 1, 1))
        _, g_pgrad = polynomial_gradient(tc[:, None], [0.05], [1], [0.25])
        g2_xs = np.zeros((n, 1, 6))
        g2_xs[:, 0, 0] = g_pgrad[:, 0]
        out[("g_2", "x_shared")] = g2_xs
        return out


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
    units = {**dict.fromkeys(inputs + outputs, "1"), "y_23": "lb", "y_31": "lb", "y_34": "1/h"}
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

    def compute_partials(self, inputs):
        _, h, mach, _, _, _ = _split_shared(inputs["x_shared"])
        throttle, drag = inputs["x_3"], inputs["y_23"]
        n = len(h)
        thrust = throttle * THROTTLE_SCALE
        c = SFC_COEFF
        dsfc_dmach = c[1] + 2 * c[4] * mach + 2 * h * c[5] + 2 * thrust * c[6]
        dsfc_dh = c[2] + 2 * mach * c[5] + 2 * c[7] * h + 2 * thrust * c[8]
        dsfc_dthrottle = (c[3] + 2 * mach * c[6] + 2 * h * c[8] + 2 * c[9] * thrust) * THROTTLE_SCALE
        esf = drag / (3.0 * thrust)
        desf_ddrag, desf_dthrottle = 1.0 / (3.0 * thrust), -esf / throttle
        dwe_desf = 3.0 * REF_ENGINE_WEIGHT * 1.05 * esf ** 0.05
        t = THROTTLE_UPPER_COEFF
        upper = t[0] + t[1] * mach + t[2] * h + t[3] * mach ** 2 + 2 * t[4] * mach * h + t[5] * h ** 2
        dupper_dmach = t[1] + 2 * t[3] * mach + 2 * t[4] * h
        dupper_dh = t[2] + 2 * t[4] * mach + 2 * t[5] * h
        _, g_temp = polynomial_gradient(np.column_stack([mach, h, throttle]), [1.6, 45000.0, 0.5], [2, 4, 2], 0.25)
        sfc_xs = np.zeros((n, 1, 6))
        sfc_xs[:, 0, 1], sfc_xs[:, 0, 2] = dsfc_dh, dsfc_dmach
        g3_xs, g3_x3, g3_y23 = _jac(n, 4, 6), _jac(n, 4, 1), _jac(n, 4, 1)
        g3_xs[:, 2, 1] = -thrust * dupper_dh / upper ** 2
        g3_xs[:, 2, 2] = -thrust * dupper_dmach / upper ** 2
        g3_xs[:, 3, 1], g3_xs[:, 3, 2] = g_temp[:, 1], g_temp[:, 0]
        g3_x3[:, 0, 0], g3_x3[:, 1, 0] = desf_dthrottle, -desf_dthrottle
        g3_x3[:, 2, 0], g3_x3[:, 3, 0] = THROTTLE_SCALE / upper, g_temp[:, 2]
        g3_y23[:, 0, 0], g3_y23[:, 1, 0] = desf_ddrag, -desf_ddrag
        return {("y_31", "x_3"): dwe_desf * desf_dthrottle, ("y_31", "y_23"): dwe_desf * desf_ddrag,
                ("y_32", "x_3"): desf_dthrottle, ("y_32", "y_23"): desf_ddrag,
                ("y_34", "x_shared"): sfc_xs, ("y_34", "x_3"): dsfc_dthrottle,
                ("g_3", "x_shared"): g3_xs, ("g_3", "x_3"): g3_x3, ("g_3", "y_23"): g3_y23}


class Mission:
    """Discipline 4: the Breguet range (nmi)."""

    name = "mission"
    inputs = ("x_shared", "y_14", "y_24", "y_34")
    outputs = ("y_4",)
    units = {**dict.fromkeys(inputs + outputs, "1"), "y_14": "lb", "y_34": "1/h", "y_4": "nmi"}
    shapes = {"x_shared": 6, "y_14": 2}

    def compute(self, inputs):
        _, h, mach, _, _, _ = _split_shared(inputs["x_shared"])
        total_weight, fuel_weight = inputs["y_14"][:, 0], inputs["y_14"][:, 1]
        sqrt_theta = np.where(h < 36089.0, np.sqrt(np.abs(1.0 - 6.875e-6 * h)), np.sqrt(0.7519))
        with np.errstate(invalid="ignore", divide="ignore"):  # W_t <= W_f: NaN, a failed point
            log_ratio = np.log(total_weight / (total_weight - fuel_weight))
        return {"y_4": mach * inputs["y_24"] * 661.0 * sqrt_theta / inputs["y_34"] * log_ratio}

    def compute_partials(self, inputs):
        _, h, mach, _, _, _ = _split_shared(inputs["x_shared"])
        total_weight, fuel_weight = inputs["y_14"][:, 0], inputs["y_14"][:, 1]
        lift_drag, sfc = inputs["y_24"], inputs["y_34"]
        n = len(h)
        low = h < 36089.0
        theta = np.where(low, np.abs(1.0 - 6.875e-6 * h), 0.7519)
        factor = mach * lift_drag * 661.0 * np.sqrt(theta) / sfc
        with np.errstate(invalid="ignore", divide="ignore"):
            log_ratio = np.log(total_weight / (total_weight - fuel_weight))
            empty = total_weight - fuel_weight
        ac_range = factor * log_ratio
        xs = np.zeros((n, 1, 6))
        xs[:, 0, 1] = np.where(low, ac_range * 0.5 * -6.875e-6 / theta, 0.0)
        xs[:, 0, 2] = ac_range / mach
        w = np.stack([factor * (1.0 / total_weight - 1.0 / empty), factor / empty], axis=1)[:, None, :]
        return {("y_4", "x_shared"): xs, ("y_4", "y_14"): w, ("y_4", "y_24"): ac_range / lift_drag,
                ("y_4", "y_34"): -ac_range / sfc}
