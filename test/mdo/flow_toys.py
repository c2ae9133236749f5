"""A feed-forward chain of toy disciplines that fail at chosen points (test_flow.py, and as ROS nodes
in test/ros/test_point_errors.py: ``flow_toys:Square`` with this folder on the config's search_path)."""
import numpy as np

from bev_mdo.mdo.discipline import Discipline


class Square(Discipline):
    """y = x^2; fails (raises) where x < 0."""
    name, inputs, outputs = "square", ("x",), ("y",)

    def compute(self, inputs):
        if (inputs["x"] < 0).any():
            raise ValueError("x must be >= 0")
        return {"y": inputs["x"] ** 2}


class Plus(Discipline):
    """w = y + z; NaN where z > 5."""
    name, inputs, outputs = "plus", ("y", "z"), ("w",)
    parameters = {"offset": 0.0}

    def compute(self, inputs):
        w = inputs["y"] + inputs["z"] + inputs.get("offset", 0.0)
        return {"w": np.where(inputs["z"] > 5, np.nan, w)}


class Half(Discipline):
    name, inputs, outputs = "half", ("w",), ("v",)

    def compute(self, inputs):
        return {"v": 0.5 * inputs["w"]}


class Side(Discipline):
    """Independent of the others: u = 2 x."""
    name, inputs, outputs = "side", ("x",), ("u",)

    def compute(self, inputs):
        return {"u": 2 * inputs["x"]}


for _toy in (Square, Plus, Half, Side):
    _toy.units = dict.fromkeys(_toy.inputs + _toy.outputs, "1")  # dimensionless


def chain():
    return [Square(), Plus(), Half(), Side()]


class Pre(Discipline):
    """a = x; fails (NaN) where x < 0, so the loop after it runs on fewer rows than the batch."""
    name, inputs, outputs = "pre", ("x",), ("a",)

    def compute(self, inputs):
        return {"a": np.where(inputs["x"] < 0, np.nan, inputs["x"])}


class LoopA(Discipline):
    """y1 = a + 0.5 y2 (a loop with LoopB); raises where a > 5."""
    name, inputs, outputs = "loop_a", ("a", "y2"), ("y1",)

    def compute(self, inputs):
        if (inputs["a"] > 5).any():
            raise ValueError("a must be <= 5")
        return {"y1": inputs["a"] + 0.5 * inputs["y2"]}


class LoopB(Discipline):
    """y2 = 0.5 y1."""
    name, inputs, outputs = "loop_b", ("y1",), ("y2",)

    def compute(self, inputs):
        return {"y2": 0.5 * inputs["y1"]}


def loop():
    return [Pre(), LoopA(), LoopB()]


# point 0 fails in pre; points 2 and 3 in loop_a (the loop's second and third rows); point 1 converges
LOOP_X = {"x": np.array([-1.0, 1.0, 7.0, 8.0])}


for _toy in (Pre, LoopA, LoopB):
    _toy.units = dict.fromkeys(_toy.inputs + _toy.outputs, "1")  # dimensionless
