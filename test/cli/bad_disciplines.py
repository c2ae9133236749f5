"""User disciplines that fail on purpose (test_failures.py)."""
from __future__ import annotations

import time

import numpy as np


class Hang:
    """Never returns."""

    name = "hang"
    inputs = ("motor_kw",)
    outputs = ("hang_kw",)

    def compute(self, inputs):
        time.sleep(3600)
        return {"hang_kw": np.asarray(inputs["motor_kw"])}


class Broken:
    """Raises for every point."""

    name = "broken"
    inputs = ("motor_kw",)
    outputs = ("broken_kw",)

    def compute(self, inputs):
        raise ValueError("the broken model refuses every motor")


class Summed:
    """Returns one number for the whole batch (a sum over it), not one per point."""

    name = "summed"
    inputs = ("motor_kw",)
    outputs = ("summed_kw",)

    def compute(self, inputs):
        return {"summed_kw": float(np.sum(inputs["motor_kw"]))}
