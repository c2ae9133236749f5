"""Broken user disciplines for the bad-input tests (each mistake a user can make)."""
from __future__ import annotations

import time

import numpy as np


class OutputTwice:
    name = "twice"
    inputs = ("z1",)
    outputs = ("w", "w")
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"w": inputs["z1"]}


class WrongShape:
    name = "wrong_shape"
    inputs = ("z1", "x")
    outputs = ("w",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        return {"w": np.column_stack([inputs["z1"], inputs["x"]])}  # (N, 2), not (N,)


class Raises:
    name = "raises"
    inputs = ("z1", "x")
    outputs = ("w",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def compute(self, inputs):
        raise RuntimeError("the solver diverged")


class ReturnsNaN:
    name = "returns_nan"
    inputs = ("z1", "x")
    outputs = ("w",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def __init__(self, above=None):
        self.above = above  # NaN only where x > above (None: everywhere)

    def compute(self, inputs):
        bad = np.ones(inputs["z1"].shape, bool) if self.above is None else inputs["x"] > self.above
        return {"w": np.where(bad, np.nan, inputs["z1"])}


class Hangs:
    name = "hangs"
    inputs = ("z1", "x")
    outputs = ("w",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def __init__(self, seconds=3600.0):
        self.seconds = float(seconds)

    def compute(self, inputs):
        if inputs["z1"].size:
            time.sleep(self.seconds)
        return {"w": inputs["z1"]}


class BadConstructor:
    name = "bad_constructor"
    inputs = ("z1",)
    outputs = ("w",)
    units = dict.fromkeys(inputs + outputs, "1")  # dimensionless

    def __init__(self):
        raise KeyError("licence server")
