"""GEMSEO's aerostructure toy problem as a user writes it for bev_mdo: three plain classes.

Source: GEMSEO (IRT Saint Exupery), ``gemseo.problems.mdo.aerostructure`` (M. De Lozzo; LGPL-3.0)
and its example ``plot_aerostructure.py`` (F. Gallard; BSD-0). The equations below are re-typed
from GEMSEO's code (not from its docstring, which has the sign of ``3 sweep`` in the reserve
factor and the range formula ``lift mass / drag`` wrong against the code); no GEMSEO code is used:

    aerodynamics(sweep, thick_airfoils, displ):
        drag   = 0.1 ((sweep/360)^2 + 200 + thick_airfoils^2 - thick_airfoils - 4 displ)
        forces = 10 sweep + 0.2 thick_airfoils - 0.2 displ
        lift   = (sweep + 0.2 thick_airfoils - 2 displ) / 3000
    structure(sweep, thick_panels, forces):
        mass         = 4000 (sweep/360)^3 + 200000 + 100 thick_panels + 200 forces
        reserve_fact = -3 sweep - 6 thick_panels + 0.1 forces + 55
        displ        = 2 sweep + 3 thick_panels - 2 forces
    mission(lift, mass, drag):
        range = 8e11 lift / (mass drag)

A loop forces <-> displ (aerodynamics <-> structure; a Gauss-Seidel sweep contracts it by 0.4).
GEMSEO's example problem: maximise range over thick_airfoils in [5, 25], thick_panels in [1, 20],
sweep in [10, 35], subject to reserve_fact <= 0.5 and lift = 0.5.

The optimum (exact: both constraints active, thick_airfoils on its lower bound; the couplings are
linear, so two linear equations in sweep and thick_panels): sweep = 24.99326599, thick_panels =
3.22558923, thick_airfoils = 5, range = 4509.5054469 (GEMSEO 6.3.3 SLSQP: MDF 4509.50547, with
reserve_fact 3.2e-5 above its bound; IDF 4509.50545). See docs/aerostructure.md.

GEMSEO's Mission also outputs c_lift = lift - 0.5 and c_rf = reserve_fact - 0.5; here the
constraints are put on lift and reserve_fact themselves, as GEMSEO's example does.
"""
from __future__ import annotations

import numpy as np

OPTIMUM = {"thick_airfoils": 5.0, "thick_panels": 3.2255892255892404, "sweep": 24.99326599326595}
OPTIMUM_RANGE = 4509.505446927924


class Aerodynamics:
    name = "aerodynamics"
    inputs = ("sweep", "thick_airfoils", "displ")
    outputs = ("drag", "forces", "lift")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        s, ta, d = inputs["sweep"], inputs["thick_airfoils"], inputs["displ"]
        return {"drag": 0.1 * ((s / 360.0) ** 2 + 200.0 + ta ** 2 - ta - 4.0 * d),
                "forces": 10.0 * s + 0.2 * ta - 0.2 * d,
                "lift": (s + 0.2 * ta - 2.0 * d) / 3000.0}

    def compute_partials(self, inputs):
        s, ta = inputs["sweep"], inputs["thick_airfoils"]
        n = len(s)
        c = lambda v: np.full(n, v)  # noqa: E731
        return {("drag", "sweep"): 0.2 * s / 360.0 ** 2, ("drag", "thick_airfoils"): 0.1 * (2.0 * ta - 1.0),
                ("drag", "displ"): c(-0.4),
                ("forces", "sweep"): c(10.0), ("forces", "thick_airfoils"): c(0.2), ("forces", "displ"): c(-0.2),
                ("lift", "sweep"): c(1.0 / 3000.0), ("lift", "thick_airfoils"): c(0.2 / 3000.0),
                ("lift", "displ"): c(-2.0 / 3000.0)}


class Structure:
    name = "structure"
    inputs = ("sweep", "thick_panels", "forces")
    outputs = ("mass", "reserve_fact", "displ")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        s, tp, f = inputs["sweep"], inputs["thick_panels"], inputs["forces"]
        return {"mass": 4000.0 * (s / 360.0) ** 3 + 200000.0 + 100.0 * tp + 200.0 * f,
                "reserve_fact": -3.0 * s - 6.0 * tp + 0.1 * f + 55.0,
                "displ": 2.0 * s + 3.0 * tp - 2.0 * f}

    def compute_partials(self, inputs):
        s = inputs["sweep"]
        n = len(s)
        c = lambda v: np.full(n, v)  # noqa: E731
        return {("mass", "sweep"): 12000.0 * s ** 2 / 360.0 ** 3, ("mass", "thick_panels"): c(100.0),
                ("mass", "forces"): c(200.0),
                ("reserve_fact", "sweep"): c(-3.0), ("reserve_fact", "thick_panels"): c(-6.0),
                ("reserve_fact", "forces"): c(0.1),
                ("displ", "sweep"): c(2.0), ("displ", "thick_panels"): c(3.0), ("displ", "forces"): c(-2.0)}


class Mission:
    name = "mission"
    inputs = ("lift", "mass", "drag")
    outputs = ("range",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"range": 8e11 * inputs["lift"] / (inputs["mass"] * inputs["drag"])}

    def compute_partials(self, inputs):
        lift, mass, drag = inputs["lift"], inputs["mass"], inputs["drag"]
        r = 8e11 * lift / (mass * drag)
        return {("range", "lift"): 8e11 / (mass * drag), ("range", "mass"): -r / mass, ("range", "drag"): -r / drag}
