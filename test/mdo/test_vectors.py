"""Vector variables: declaration, flattening to name[i] columns, validation, the vector Sellar problem."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.discipline import run_discipline
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.problem import Problem
from bev_mdo.mdo.vectors import ShapeError, VectorDiscipline, wrap
from examples.sellar_vector import REFERENCE, SellarFunctions


ROOT = Path(__file__).resolve().parents[2]
SELLAR = ROOT / "examples" / "sellar_vector.yaml"


def test_a_vector_design_variable_is_its_elements_with_broadcast_and_per_element_values():
    p = Problem.from_config({"objective": "f", "design_variables": {
        "z": {"shape": 3, "lower": [-1, 0, 1], "upper": 10, "initial": [0, 1, 2], "scale": 2},
        "x": {"lower": 0, "upper": 1}},
        "constraints": {"g": {"shape": 2, "upper": [0, 1]}}})
    assert p.names == ["z[0]", "z[1]", "z[2]", "x"]
    assert p.array("lower").tolist() == [-1, 0, 1, 0] and p.array("upper").tolist() == [10, 10, 10, 1]
    assert p.x0().tolist() == [0, 1, 2, 0.5] and p.array("scale").tolist() == [2, 2, 2, 1]
    assert [(c.name, c.upper) for c in p.constraints] == [("g[0]", 0), ("g[1]", 1)]
    assert p.shapes == {"z": 3, "g": 2}


@pytest.mark.parametrize("spec, words", [
    ({"shape": 3, "lower": [0, 1], "upper": 5}, "has 2 values, expected 3"),
    ({"lower": [0, 1], "upper": 5}, "needs shape"),
    ({"shape": 0, "lower": 0, "upper": 5}, "positive integer"),
    ({"shape": 2, "lower": 0, "upper": 5, "initial": [1, 7]}, "z[1].initial"),
])
def test_bad_vector_specs_give_one_line_naming_the_key(spec, words):
    with pytest.raises(ValueError, match=None) as exc:
        Problem.from_config({"objective": "f", "design_variables": {"z": spec}})
    assert words in str(exc.value) and "problem.design_variables.z" in str(exc.value)
    assert "\n" not in str(exc.value)


def test_a_vector_discipline_is_seen_as_scalar_columns():
    d = wrap(SellarFunctions())
    assert isinstance(d, VectorDiscipline)
    assert d.inputs == ("x", "z[0]", "z[1]", "y1", "y2") and d.outputs == ("obj", "con[0]", "con[1]")
    res = run_discipline(d, {"x": [0.0, 1.0], "z[0]": [1.0, 1.0], "z[1]": [0.0, 2.0], "y1": [3.0, 4.0],
                             "y2": [5.0, 30.0]})
    assert res.ok.all()
    assert res.outputs["con[0]"].tolist() == pytest.approx([0.16, -0.84])
    assert res.outputs["con[1]"].tolist() == pytest.approx([-19.0, 6.0])


def test_one_scalar_for_a_batch_is_an_error_naming_the_discipline_unless_declared():
    from vector_toys import ConstantOnPurpose, ScalarForBatch

    d = wrap(ScalarForBatch())
    with pytest.raises(ShapeError, match=r"discipline 'sellar_dis1': output 'y1' has shape \(\), expected \(2,\)"):
        run_discipline(d, {"z[0]": [1.0, 2.0], "z[1]": [0.0, 0.0], "x": [0.0, 0.0], "y2": [1.0, 1.0]})
    res = run_discipline(ConstantOnPurpose(), {"x": [1.0, 2.0, 3.0]})
    assert res.outputs["c"].tolist() == [2.0, 2.0, 2.0]


def test_an_output_named_twice_is_refused_naming_the_discipline():
    from vector_toys import TwiceNamed

    with pytest.raises(ValueError, match="discipline 'sellar_dis1' names output 'y1' twice"):
        wrap(TwiceNamed())
    cfg = {"name": "t", "disciplines": [{"name": "sellar_dis1", "class": "vector_toys:TwiceNamed"}],
           "problem": {"objective": "y1", "design_variables": {"x": {"lower": 0, "upper": 1}}}}
    with pytest.raises(ValueError, match=r"\(sellar_dis1\): outputs name \['y1'\] twice"):
        load_config(cfg)


def test_a_constraint_on_a_vector_output_without_shape_says_how_to_fix_it():
    import yaml

    raw = yaml.safe_load(SELLAR.read_text())
    raw["problem"]["constraints"] = {"con": {"upper": 0}}
    with pytest.raises(ValueError, match=r"'con' is a vector of 2 elements .*add shape: 2"):
        load_config(raw)


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
@pytest.mark.parametrize("derivatives", ["analytic", "fd"])
def test_vector_sellar_reaches_its_published_optimum(formulation, derivatives):
    cfg = load_config(SELLAR)
    cfg["optimizer"]["derivatives"] = derivatives
    res = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), formulation=formulation)
    assert res.success and res.feasible
    assert res.objective == pytest.approx(REFERENCE["objective"], abs=1e-6)
    assert res.design["z[0]"] == pytest.approx(REFERENCE["z"][0], abs=1e-5)
    assert res.design["z[1]"] == pytest.approx(0.0, abs=1e-6) and res.design["x"] == pytest.approx(0.0, abs=1e-6)
    assert set(res.constraints) == {"con[0]", "con[1]"}
    assert res.history[-1]["design"].keys() == {"z[0]", "z[1]", "x"}


def test_history_csv_names_vector_elements():
    from bev_mdo.bag.history import to_csv

    cfg = load_config(SELLAR)
    res = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
    header = to_csv([{**r, "run_id": "r", "sequence": k, "log_time_ns": 0}
                     for k, r in enumerate(res.history)]).splitlines()[0].split(",")
    assert {"design.z[0]", "design.z[1]", "design.x", "constraint.con[0]", "constraint.con[1]"} <= set(header)


GOLINSKI = ROOT / "examples" / "golinski.yaml"


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
@pytest.mark.parametrize("derivatives", ["auto", "fd"])
def test_golinski_speed_reducer_reaches_its_published_optimum(formulation, derivatives):
    """W = 2994.47 at (3.5, 0.7, 17, 7.3, 7.71532, 3.35021, 5.28665) (Kodiyalam 1998, Ray 2003).
    Tolerance: 0.01 on W (the reference has 6 digits), 1e-4 on every variable (references give 5-6)."""
    from examples.golinski import REFERENCE

    cfg = load_config(GOLINSKI)
    cfg["optimizer"]["derivatives"] = derivatives
    res = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), formulation=formulation)
    assert res.success and res.feasible
    assert res.objective == pytest.approx(REFERENCE["weight"], abs=0.01)
    for name in ("x_shared", "x_shaft1", "x_shaft2"):
        for i, v in enumerate(REFERENCE[name]):
            assert res.design[f"{name}[{i}]"] == pytest.approx(v, abs=1e-4), f"{name}[{i}]"
    assert len(res.constraints) == 11


def test_golinski_analytic_gradient_is_one_analysis_per_gradient():
    cfg = load_config(GOLINSKI)
    res = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
    # every discipline has partials: no FD in the optimisation; the end-point check's two central-difference
    # stencils (which confirm the assembled derivatives) and its steps either side (a kink) are its own cost
    assert res.mda_evaluations - res.first_order["cost"]["points"] == res.gradients
    assert res.first_order["derivatives_confirmed"] and res.first_order["cost"]["batches"] == 3
    assert set(res.discipline_evaluations.values()) == {res.mda_evaluations}


def test_golinski_with_trust_constr_reaches_it_through_points_outside_the_bounds(monkeypatch):
    """trust-constr's bounds are not keep_feasible: its interior-point iterates step outside them (the
    formulation counts such a point as violated, and it is never the result). With keep_feasible=True it
    never steps out, but ends infeasible at W 2779 here (and on SSBJ MDF, propane IDF): kept off."""
    import numpy as np
    from examples.golinski import REFERENCE

    from bev_mdo.mdo import formulations

    cfg = load_config(GOLINSKI)
    outside = []
    inner = formulations.Formulation.evaluate_batch

    def evaluate_batch(self, X):
        X = np.atleast_2d(X)
        outside.extend(np.any((X < self.lower) | (X > self.upper), axis=1))
        return inner(self, X)

    monkeypatch.setattr(formulations.Formulation, "evaluate_batch", evaluate_batch)
    res = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)), optimizer="trust-constr")
    assert res.feasible and res.verdict == "optimum"
    assert res.objective == pytest.approx(REFERENCE["weight"], abs=0.01)
    assert any(outside)


def test_a_masked_output_value_is_no_value():
    """A malformed-files trial: a discipline returning a fully masked array had its mask ignored and the data under
    it taken as values. A masked point has no value: it fails, the others stand."""
    import numpy as np

    class Masked:
        name, inputs, outputs = "masked", ("x",), ("y",)

        def compute(self, inputs):
            return {"y": np.ma.masked_array(2.0 * inputs["x"], mask=inputs["x"] > 1.5)}

    res = run_discipline(Masked(), {"x": [1.0, 2.0, 3.0]})
    assert res.ok.tolist() == [True, False, False] and res.outputs["y"][0] == 2.0
    assert "masked: non-finite output ['y']" in res.error
