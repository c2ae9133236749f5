"""A user trial's three-discipline coupled problem, vector couplings in other units than their consumers read.

P [kW] = x + a Q ; Q [km] = b P + d ; f = (x0-3)^2 + (x1-2)^2 + 2 (d-1)^2 ; ptot = P0 + P1 [kW] <= 5.
The heater produces p in W (its consumers read kW); the cooler produces q in m (the heater reads km).
"""
import numpy as np


class Heater:
    name = "heater"
    inputs = ("x", "q")
    outputs = ("p",)
    shapes = {"x": 2, "q": 2, "p": 2}
    units = {"x": "1", "q": "km", "p": "W"}

    def __init__(self, gain: float = 0.5, raise_above: float = 1e9):
        self.gain = gain
        self.raise_above = raise_above  # x[0] above it: the heater raises (a region without values)

    def compute(self, inputs):
        x, q = inputs["x"], inputs["q"]
        if np.any(x[:, 0] > self.raise_above):
            raise RuntimeError(f"heater melts: x[0] = {x[:, 0].max():.4g} > {self.raise_above}")
        return {"p": 1000.0 * (x + self.gain * q)}

    def compute_partials(self, inputs):
        eye = np.broadcast_to(np.eye(2), (len(inputs["x"]), 2, 2))
        return {("p", "x"): 1000.0 * eye, ("p", "q"): 1000.0 * self.gain * eye}


class Cooler:
    name = "cooler"
    inputs = ("p", "d")
    outputs = ("q",)
    shapes = {"p": 2, "q": 2}
    units = {"p": "kW", "d": "km", "q": "m"}

    def __init__(self, gain: float = 0.2):
        self.gain = gain

    def compute(self, inputs):
        return {"q": 1000.0 * (self.gain * inputs["p"] + inputs["d"][:, None])}

    def compute_partials(self, inputs):
        n = len(inputs["d"])
        return {("q", "p"): 1000.0 * self.gain * np.broadcast_to(np.eye(2), (n, 2, 2)),
                ("q", "d"): np.full((n, 2, 1), 1000.0)}


class Cost:
    name = "cost"
    inputs = ("x", "d", "p")
    outputs = ("f", "ptot")
    shapes = {"x": 2, "p": 2}
    units = {"x": "1", "d": "m", "p": "kW", "f": "USD", "ptot": "kW"}

    def compute(self, inputs):
        x, d, p = inputs["x"], inputs["d"] / 1000.0, inputs["p"]
        return {"f": (x[:, 0] - 3) ** 2 + (x[:, 1] - 2) ** 2 + 2 * (d - 1) ** 2, "ptot": p[:, 0] + p[:, 1]}

    def compute_partials(self, inputs):
        x, d = inputs["x"], inputs["d"] / 1000.0
        return {("f", "x"): np.stack([2 * (x[:, 0] - 3), 2 * (x[:, 1] - 2)], axis=1)[:, None, :],
                ("f", "d"): 4 * (d - 1) / 1000.0, ("ptot", "p"): np.ones((len(d), 1, 2))}
