"""A loop converges when its answer is within the tolerance, not only its last step. A user trial: a loop
with no fixed point (iterates running off to infinity by steady steps) passed the relative-change test at a
loose tolerance after 1,428 Gauss-Seidel iterations, and the run ended "verdict: optimum" at y1 = 4,204;
and a slowly contracting loop stopped where its true error was many times its last step."""
from __future__ import annotations

import numpy as np
import pytest

from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA


class D1:
    name, inputs, outputs = "d1", ("x1", "y2"), ("y1",)
    units = dict.fromkeys(inputs + outputs, "1")

    def compute(self, i):
        return {"y1": i["x1"] ** 2 + 0.5 * i["y2"]}


class D2:
    name, inputs, outputs = "d2", ("x2", "y3"), ("y2",)
    units = dict.fromkeys(inputs + outputs, "1")

    def __init__(self, k=0.4):
        self.k = k

    def compute(self, i):
        return {"y2": i["x2"] + self.k * i["y3"] + 0.1 * np.sin(i["y3"])}


class D3:
    name, inputs, outputs = "d3", ("x1", "x2", "y1"), ("y3",)
    units = dict.fromkeys(inputs + outputs, "1")

    def compute(self, i):
        return {"y3": 0.6 * i["y1"] + i["x1"] * i["x2"]}


class FObj:
    name, inputs, outputs = "fobj", ("x1", "x2", "y1", "y3"), ("f", "g")
    units = dict.fromkeys(inputs + outputs, "1")

    def compute(self, i):
        return {"f": (i["x1"] - 3) ** 2 + (i["x2"] - 2) ** 2 + 0.1 * i["y1"], "g": 1.0 * i["y3"]}


POINT = {"x1": np.array([5.0]), "x2": np.array([1.2])}


@pytest.mark.parametrize("method, iterations", [("gauss_seidel", 5000), ("jacobi", 5000), ("newton", 100)])
def test_a_loop_without_a_fixed_point_does_not_converge_at_a_loose_tolerance(method, iterations):
    # 0.5 x 0.6 x 10/3 = 1: y1 = x1^2 + 0.5 (x2 + 10/3 (0.6 y1 + x1 x2) + 0.1 sin y3) has no solution here
    res = MDA(InProcessEvaluator([D1(), D2(10 / 3), D3()]), method=method, tolerance=1e-3,
              max_iterations=iterations).run(POINT)
    assert not res.ok[0]
    assert res.errors[0].kind == "not_converged" and "the changes do not shrink fast enough" in res.messages[0]


@pytest.mark.parametrize("method", ["gauss_seidel", "jacobi", "newton"])
def test_a_contracting_loop_still_converges_to_its_fixed_point(method):
    res = MDA(InProcessEvaluator([D1(), D2(0.4), D3()]), method=method, tolerance=1e-10,
              max_iterations=500).run(POINT)
    assert res.ok[0]
    y1 = res.values["y1"][0]  # the fixed point, solved by hand: y1 - x1^2 - 0.5 y2(y3(y1)) = 0
    y3 = 0.6 * y1 + 6.0
    assert y1 == pytest.approx(25.0 + 0.5 * (1.2 + 0.4 * y3 + 0.1 * np.sin(y3)), rel=1e-10)  # the tolerance


def test_a_slow_loop_stops_where_its_answer_is_within_the_tolerance():
    # y1 = 25 + 0.5 y2, y2 = 1.2 + k y3, y3 = 0.6 y1 + 6 with 0.5 x 0.6 x k = 0.95: 0.95 per Gauss-Seidel
    # sweep; where the last step is 1e-6 of y1, the distance still to go is 19 times that
    k = 0.95 / 0.3
    exact = (25.0 + 0.5 * (1.2 + 6.0 * k)) / (1.0 - 0.3 * k)  # 702, without D2's 0.1 sin y3 (Linear)

    class Linear(D2):
        def compute(self, i):
            return {"y2": i["x2"] + self.k * i["y3"]}

    res = MDA(InProcessEvaluator([D1(), Linear(k), D3()]), method="gauss_seidel", tolerance=1e-6,
              max_iterations=5000).run(POINT)
    assert res.ok[0]
    assert abs(res.values["y1"][0] - exact) <= 2e-6 * exact


def test_an_idf_end_point_whose_analysis_fails_is_not_called_an_optimum(tmp_path, capsys):
    # a user trial: IDF ended at a consistent point, the MDA through it (Gauss-Seidel on a loop of gain 1)
    # did not converge, and the run said "verdict: optimum", success true, beside feasible false and no outputs
    import json
    from pathlib import Path

    import yaml

    from bev_mdo.cli import main

    here = str(Path(__file__).resolve().parent)
    raw = {"name": "gain_one_idf", "search_path": [here],
           "disciplines": [{"name": "d1", "class": "test_mda_settles:D1"},
                           {"name": "d2", "class": "test_mda_settles:D2", "options": {"k": 10 / 3}},
                           {"name": "d3", "class": "test_mda_settles:D3"},
                           {"name": "fobj", "class": "test_mda_settles:FObj"}],
           "problem": {"objective": "f", "constraints": {"g": {"upper": 6}},
                       "design_variables": {"x1": {"lower": 0, "upper": 5, "initial": 1},
                                            "x2": {"lower": 0, "upper": 1.2, "initial": 1}}},
           "formulation": "idf",
           "mda": {"method": "gauss_seidel", "tolerance": 1.0e-10, "max_iterations": 100, "relaxation": 0.8},
           "optimizer": {"name": "SLSQP", "fd_step": 1.0e-7}}
    path = tmp_path / "gain_one_idf.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    code = main(["optimize", str(path), "--transport", "inprocess", "--no-record", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 1 and doc["feasible"] is False
    assert doc["verdict"] == "infeasible" and doc["success"] is False
    assert "did not converge" in doc["first_order"]["failure"]
