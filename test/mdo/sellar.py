"""OpenMDAO's Sellar problem as bev_mdo disciplines (known MDF optimum z=(1.9776, 0), x=0, obj 3.18339)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

# The disciplines are the user-facing example's (examples/sellar/sellar_disciplines.py), the same classes.
_EXAMPLE = str(Path(__file__).resolve().parents[2] / "examples" / "sellar")
if _EXAMPLE not in sys.path:
    sys.path.insert(0, _EXAMPLE)
from sellar_disciplines import (REFERENCE_OBJECTIVE, REFERENCE_OPTIMUM, SellarDis1, SellarDis2,  # noqa: E402
                                SellarObjective)

SELLAR_OPTIMUM = {"z1": 1.97763888, "z2": 0.0, "x": 0.0}
SELLAR_OBJECTIVE = REFERENCE_OBJECTIVE
assert SELLAR_OPTIMUM.keys() == REFERENCE_OPTIMUM.keys()


class NegatedObjective:
    """-obj, for maximisation tests (maximise -obj == minimise obj)."""

    name = "sellar_neg"
    inputs = ("obj",)
    outputs = ("neg_obj",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"neg_obj": -inputs["obj"]}

    def compute_partials(self, inputs):  # like the example's disciplines: the same (analytic) gradient path
        return {("neg_obj", "obj"): np.full(len(inputs["obj"]), -1.0)}


class Failing:
    """Wraps a discipline; returns NaN where the input ``fail_above`` variable exceeds a threshold."""

    def __init__(self, inner, var, threshold):
        self.inner, self.var, self.threshold = inner, var, threshold
        self.name, self.inputs, self.outputs = inner.name, inner.inputs, inner.outputs
        self.units = getattr(inner, "units", {})

    def compute(self, inputs):
        out = self.inner.compute(inputs)
        bad = inputs[self.var] > self.threshold
        return {k: np.where(bad, np.nan, v) for k, v in out.items()}


def sellar_disciplines():
    return [SellarDis1(), SellarDis2(), SellarObjective()]


SELLAR_PROBLEM = {
    "objective": "obj",
    "design_variables": {
        "z1": {"lower": -10.0, "upper": 10.0, "initial": 5.0},
        "z2": {"lower": 0.0, "upper": 10.0, "initial": 2.0},
        "x": {"lower": 0.0, "upper": 10.0, "initial": 1.0},
    },
    "constraints": {"y1": {"lower": 3.16}, "y2": {"upper": 24.0}},
}
