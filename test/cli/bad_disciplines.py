"""User disciplines that fail on purpose (test_failures.py)."""
from __future__ import annotations

import time

import numpy as np


class Hang:
    """Never returns."""

    name = "hang"
    inputs = ("motor_kw",)
    outputs = ("hang_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")

    def compute(self, inputs):
        time.sleep(3600)
        return {"hang_kw": np.asarray(inputs["motor_kw"])}


class HangLater:
    """Answers its first ``after`` calls (2: the start point, its MDA and the baseline), then never returns."""

    name = "late"
    inputs = ("motor_kw",)
    outputs = ("late_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")
    after = 2
    calls = 0  # per class (each subclass counts its own)

    def compute(self, inputs):
        type(self).calls += 1
        if type(self).calls > self.after:
            time.sleep(3600)
        return {self.outputs[0]: np.asarray(inputs["motor_kw"], float)}


class OnlyAtStart:
    """Answers at the start design (80 kW, 8:1, 24 kWh) and raises everywhere else: the start point's
    whole neighbourhood fails, as when a discipline breaks (or hangs) after the start point."""

    name = "only"
    inputs = ("motor_kw", "gear_ratio", "battery_kwh")
    outputs = ("only_kw",)
    units = {"motor_kw": "kW", "gear_ratio": "1", "battery_kwh": "kWh", "only_kw": "kW"}

    def compute(self, inputs):
        x = [np.asarray(inputs[k], float) for k in self.inputs]
        if not all(np.all(v == s) for v, s in zip(x, (80.0, 8.0, 24.0))):
            raise ValueError("only the start design is answered")
        return {"only_kw": x[0]}


class Broken:
    """Raises for every point."""

    name = "broken"
    inputs = ("motor_kw",)
    outputs = ("broken_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")

    def compute(self, inputs):
        raise ValueError("the broken model refuses every motor")


class Summed:
    """Returns one number for the whole batch (a sum over it), not one per point."""

    name = "summed"
    inputs = ("motor_kw",)
    outputs = ("summed_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")

    def compute(self, inputs):
        return {"summed_kw": float(np.sum(inputs["motor_kw"]))}


class Quits:
    """Calls sys.exit(3) for every point (a user script's habit)."""

    name = "quits"
    inputs = ("motor_kw",)
    outputs = ("quits_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")

    def compute(self, inputs):
        import sys

        sys.exit(3)


class WrongShapeLater:
    """Answers its first 60 calls, then returns an output of the wrong shape (a wiring mistake that
    stops the run with an error, after some iterations were recorded)."""

    name = "shape"
    inputs = ("motor_kw",)
    outputs = ("shape_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")
    calls = 0

    def compute(self, inputs):
        WrongShapeLater.calls += 1
        motor = np.asarray(inputs["motor_kw"], float)
        return {"shape_kw": motor if WrongShapeLater.calls <= 60 else np.zeros(len(motor) + 3)}


class SlowStart:
    """Its one-time work (e.g. compiling a model) takes longer than the timeout budget, done by prepare() or
    else by the first call, as a numba model compiles on its first call; every later call is quick."""

    name = "slow_start"
    inputs = ("motor_kw",)
    outputs = ("slow_start_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")
    ready = False

    def prepare(self):
        time.sleep(8.0)
        self.ready = True

    def compute(self, inputs):
        if not self.ready:
            self.prepare()
        return {"slow_start_kw": np.asarray(inputs["motor_kw"])}


class NeedsPrepare:
    """Reads in compute what its prepare() sets (a model loaded once)."""

    name = "needs_prepare"
    inputs = ("motor_kw",)
    outputs = ("needs_prepare_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")

    def prepare(self):
        self.k = 2.0

    def compute(self, inputs):
        return {"needs_prepare_kw": np.asarray(inputs["motor_kw"], float) * self.k}


class PrepareFails(NeedsPrepare):
    name = "prepare_fails"
    outputs = ("prepare_fails_kw",)
    units = dict.fromkeys(NeedsPrepare.inputs + outputs, "kW")

    def prepare(self):
        raise FileNotFoundError("table.csv is missing")


class Talks:
    """Prints in compute, as a user's debugging line does."""

    name = "talks"
    inputs = ("motor_kw",)
    outputs = ("talks_kw",)
    units = dict.fromkeys(inputs + outputs, "kW")

    def compute(self, inputs):
        print("computing talks_kw")
        return {"talks_kw": np.asarray(inputs["motor_kw"], float)}


class HangInGeneration(HangLater):
    """Answers its first 4 calls (the start point, differential evolution's first population and two
    generations), then never returns."""

    name = "gen"
    outputs = ("gen_kw",)
    units = dict.fromkeys(HangLater.inputs + outputs, "kW")
    after = 4
    calls = 0
