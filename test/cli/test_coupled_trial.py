"""A user trial's three-discipline coupled problem (test/data/user_modules/therm.py: a heater producing p in W
read in kW, a cooler producing q in m read in km; f = (x0-3)^2 + (x1-2)^2 + 2 (d-1)^2 under ptot <= 5 kW) through
`bev-mdo optimize`: what the lines under the verdict say of its coupling bounds and of an end at failing points."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from bev_mdo.cli import main

MODULES = Path(__file__).resolve().parents[1] / "data" / "user_modules"


def _config(tmp_path, formulation="idf", heater=None, q_upper=1250.0, optimizer="SLSQP") -> str:
    raw = {"name": "therm", "search_path": [str(MODULES)],
           "disciplines": [{"name": "heater", "class": "therm:Heater", **({"options": heater} if heater else {})},
                           {"name": "cooler", "class": "therm:Cooler"}, {"name": "cost", "class": "therm:Cost"}],
           "problem": {"objective": "f",
                       "design_variables": {"x": {"shape": 2, "lower": 0, "upper": 5, "initial": [1, 1]},
                                            "d": {"lower": 0, "upper": 2, "initial": 0.5}},
                       "constraints": {"ptot": {"upper": 5}}, "coupling_guesses": {"q": 0.0},
                       "coupling_bounds": {"q": {"lower": 0, "upper": q_upper}, "p": {"lower": 0, "upper": 20000}}},
           "formulation": formulation, "mda": {"method": "newton", "tolerance": 1e-12, "max_iterations": 200},
           "optimizer": {"name": optimizer}}
    path = tmp_path / "therm.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return str(path)


def _optimize(path, *argv):
    return main(["optimize", path, "--transport", "inprocess", "--no-record", "--quiet", *argv])


def test_an_idf_coupling_on_its_bound_prints_its_value(tmp_path, capsys):
    """'on its upper bound: q[0] = nan m' while the table showed 1250: the value was looked up among the design
    variables only."""
    assert _optimize(_config(tmp_path)) == 0
    out = capsys.readouterr().out
    assert "  on its upper bound: q[0] = 1250 m, multiplier 0.3597 (-0.0002878 USD per m raised)" in out, out
    assert "nan" not in out


def test_a_derivative_free_end_next_to_failing_points_says_so(tmp_path, capsys):
    """COBYQA (MDF) ended 7e-5 inside the region where the heater raises (x[0] > 2.2); the note blamed the analytic
    partials, 'the optimiser's own' gradient, while SLSQP's said the end lies at the edge of the region where the
    disciplines give values. The end-point check's first steps (1e-7) did not reach the edge; its second do."""
    assert _optimize(_config(tmp_path, "mdf", heater={"raise_above": 2.2}, q_upper=10000.0), "--optimizer",
                     "COBYQA") == 5
    out = capsys.readouterr().out
    notes = [line for line in out.splitlines() if line.startswith("note: ")]
    failed = [line for line in notes if " point(s) of the run gave no value; the first: " in line]
    (note,) = [line for line in notes if line not in failed]  # and the count of the points that gave none
    assert len(failed) == 1, out
    assert note.startswith("note: COBYQA says it converged") and "a small step from it in x[0] fails" in note, out
    assert "edge of the region where the disciplines give values" in note
    assert "optimiser's own" not in note and "wrong derivative" not in note


@pytest.mark.parametrize("at, why", [
    ("x[0]=3", "the design itself fails: move it (--at) to where the model answers"),
    ("x[0]=2.1999", "a step from the design fails: move it (--at) away from where the model gives none"),
])
def test_a_local_sensitivity_that_fails_gets_local_advice(tmp_path, capsys, at, why):
    """`sensitivity --order 2` at a design where the heater raises said 'narrow the bounds to where it answers', the
    advice of the global methods, whose samples span the bounds; a local stencil spans the design's neighbourhood."""
    path = _config(tmp_path, "mdf", heater={"raise_above": 2.2}, q_upper=10000.0)
    assert main(["sensitivity", path, "--transport", "inprocess", "--order", "2", "--at", at]) != 0
    err = capsys.readouterr().err
    assert f"points of the local stencil ({why}" in err and "narrow the bounds" not in err, err
    assert "heater melts" in err  # the failed discipline's error


def test_mdf_says_its_result_lies_beyond_a_coupling_bound_it_does_not_apply(tmp_path, capsys):
    """IDF held q[0] at its coupling bound 1250 m (f = 0.9088); MDF ended at q[0] = 1311 m, 'optimum', with no word
    that the bound, IDF's bound on its coupling variable, was not applied. A constraint holds it under both."""
    assert _optimize(_config(tmp_path, "mdf")) == 0
    out = capsys.readouterr().out
    (note,) = [line for line in out.splitlines() if line.startswith("note: ")]
    assert note.startswith("note: q[0] = 1311.11 is above its upper bound 1250 of problem.coupling_bounds:"), out
    assert "MDF, whose MDA sets the couplings, does not apply them" in note and '--constraint "q[0]<=1250"' in note
    assert _optimize(_config(tmp_path, "mdf"), "--json") == 0
    (b,) = json.loads(capsys.readouterr().out)["first_order"]["outside_coupling_bounds"]
    assert (b["name"], b["kind"], b["bound"]) == ("q[0]", "upper", 1250.0) and b["value"] == pytest.approx(1311.11)
    for formulation, q_upper in (("idf", 1250.0), ("mdf", 10000.0)):  # IDF applies it; MDF inside it: no note
        assert _optimize(_config(tmp_path, formulation, q_upper=q_upper)) == 0
        assert "coupling_bounds" not in capsys.readouterr().out
    # the constraint the note gives: both formulations end at IDF's f, q[0] on its limit
    for formulation in ("mdf", "idf"):
        assert _optimize(_config(tmp_path, formulation), "--constraint", "q[0]<=1250", "--json") == 0
        doc = json.loads(capsys.readouterr().out)
        assert doc["objective"] == pytest.approx(0.908794, rel=1e-5) and doc["verdict"] == "optimum"
        assert "outside_coupling_bounds" not in doc["first_order"]


def test_a_derivative_free_optimisers_failed_differences_are_the_checks(tmp_path, capsys):
    """A review: COBYLA ending at x = 2 where y is NaN beyond printed 'finite-difference point(s) failed and gave
    zero derivatives; the optimiser may have stopped early': COBYLA uses none; they are the first-order check's."""
    (tmp_path / "edge3.py").write_text(
        "import numpy as np\n\n\nclass D1:\n    name = 'd1'\n    inputs = ('x', 'z')\n    outputs = ('y1',)\n"
        "    units = {'x': '1', 'z': '1', 'y1': '1'}\n\n    def compute(self, inputs):\n"
        "        x, z = inputs['x'], inputs['z']\n        return {'y1': np.where(x > 2.0, np.nan, (z - 3.0) ** 2 - x)}\n")
    path = tmp_path / "edge3.yaml"
    path.write_text(yaml.safe_dump({"name": "edge3", "search_path": [str(tmp_path)],
                                    "disciplines": [{"name": "d1", "class": "edge3:D1"}],
                                    "problem": {"objective": "y1", "design_variables": {
                                        "x": {"lower": 0, "upper": 10, "initial": 1},
                                        "z": {"lower": 0, "upper": 10, "initial": 2}}}}, sort_keys=False))
    _optimize(str(path), "--optimizer", "COBYLA")
    (line,) = [s for s in capsys.readouterr().out.splitlines() if s.startswith("warning: ")]
    assert line.endswith("failed and gave zero derivatives to the first-order check (not to COBYLA, which uses none) "
                         "(see discipline_errors)"), line
