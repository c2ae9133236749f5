"""Toy disciplines for the vector and derivative tests (importable as ``vector_toys:Class``)."""
from __future__ import annotations

import numpy as np

from examples.sellar_vector import SellarDis1  # noqa: F401


class NoPartials:
    """A discipline with its partials hidden: the engine falls back to finite differences."""

    def __init__(self, inner):
        self.inner = inner
        self.name, self.inputs, self.outputs = inner.name, inner.inputs, inner.outputs
        self.units = getattr(inner, "units", {})
        self.shapes = dict(getattr(inner, "shapes", {}))

    def compute(self, inputs):
        return self.inner.compute(inputs)


class WrongPartial(SellarDis1):
    """dy1/dz[0] off by a factor of 2 (2 z0 written as 4 z0)."""

    def compute_partials(self, inputs):
        out = super().compute_partials(inputs)
        out[("y1", "z")] = out[("y1", "z")] * np.array([2.0, 1.0])
        return out


class WrongPartialShape(SellarDis1):
    def compute_partials(self, inputs):
        out = super().compute_partials(inputs)
        out[("y1", "z")] = out[("y1", "z")][:, 0, :]  # (N, 2) instead of (N, 1, 2)
        return out


class ScalarForBatch(SellarDis1):
    """Returns one number for the whole batch."""

    def compute(self, inputs):
        return {"y1": float(np.mean(super().compute(inputs)["y1"]))}


class TwiceNamed(SellarDis1):
    outputs = ("y1", "y1")


class ConstantOnPurpose:
    name = "constant"
    inputs = ("x",)
    outputs = ("c",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless
    broadcast_outputs = ("c",)

    def compute(self, inputs):
        return {"c": 2.0}
