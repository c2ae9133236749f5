"""OpenMDAO's Sellar problem as bev_mdo disciplines (known MDF optimum z=(1.9776, 0), x=0, obj 3.18339)."""
from __future__ import annotations

import numpy as np

from bev_mdo.mdo.discipline import Discipline

SELLAR_OPTIMUM = {"z1": 1.97763888, "z2": 0.0, "x": 0.0}
SELLAR_OBJECTIVE = 3.18339395


class SellarDis1(Discipline):
    name = "sellar1"
    inputs = ("z1", "z2", "x", "y2")
    outputs = ("y1",)

    def compute(self, inputs):
        return {"y1": inputs["z1"] ** 2 + inputs["z2"] + inputs["x"] - 0.2 * inputs["y2"]}


class SellarDis2(Discipline):
    name = "sellar2"
    inputs = ("z1", "z2", "y1")
    outputs = ("y2",)

    def compute(self, inputs):
        return {"y2": np.sqrt(np.abs(inputs["y1"])) + inputs["z1"] + inputs["z2"]}


class SellarObjective(Discipline):
    name = "sellar_obj"
    inputs = ("x", "z2", "y1", "y2")
    outputs = ("obj",)

    def compute(self, inputs):
        return {"obj": inputs["x"] ** 2 + inputs["z2"] + inputs["y1"] + np.exp(-inputs["y2"])}


class Failing(Discipline):
    """Wraps a discipline; returns NaN where the input ``fail_above`` variable exceeds a threshold."""

    def __init__(self, inner, var, threshold):
        self.inner, self.var, self.threshold = inner, var, threshold
        self.name, self.inputs, self.outputs = inner.name, inner.inputs, inner.outputs

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
