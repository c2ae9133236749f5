"""`bev-mdo check-totals`: the total derivatives the optimiser is given (MDF and IDF) against the
analytic totals of Sellar, and against the command's own finite differences."""
from __future__ import annotations

import json

import numpy as np
import pytest

from bev_mdo.cli import main
from bev_mdo.testing import REPO

SELLAR = REPO / "examples" / "sellar"
VARS = ("z1", "z2", "x")


def _report(capsys, config, *extra) -> dict:
    code = main(["check-totals", str(config), "--json", "--transport", "inprocess", *extra])
    rep = json.loads(capsys.readouterr().out)
    assert code == (0 if rep["ok"] else 1)
    return rep


def _totals(rep) -> dict:
    return {(r["of"], r["wrt"]): r["total"] for r in rep["rows"]}


def _mdf_analytic(z1, z2, x):
    """Sellar's coupled totals by implicit differentiation of y1 = z1^2 + z2 + x - 0.2 y2,
    y2 = sqrt(y1) + z1 + z2 at the converged couplings."""
    y2 = 1.0
    for _ in range(200):
        y1 = z1 ** 2 + z2 + x - 0.2 * y2
        y2 = np.sqrt(y1) + z1 + z2
    c = 0.5 / np.sqrt(y1)
    out = {}
    for v, a, b in (("z1", 2 * z1, 1.0), ("z2", 1.0, 1.0), ("x", 1.0, 0.0)):
        dy1 = (a - 0.2 * b) / (1 + 0.2 * c)
        dy2 = c * dy1 + b
        direct = {"z1": 0.0, "z2": 1.0, "x": 2 * x}[v]
        out[("obj", v)] = direct + dy1 - np.exp(-y2) * dy2
        out[("y1 >= 3.16", v)] = dy1
        out[("y2 <= 24", v)] = dy2
    return out


@pytest.mark.parametrize("at", ["", "z1=1.977639,z2=0.5,x=0.3"])
def test_mdf_totals_match_sellars_analytic_totals(capsys, at):
    rep = _report(capsys, SELLAR / "sellar_mdf.yaml", *(["--at", at] if at else []))
    assert rep["formulation"] == "mdf" and rep["ok"], rep
    got = _totals(rep)
    want = _mdf_analytic(*(rep["point"][v] for v in VARS))
    assert set(got) == set(want)
    for key, value in want.items():
        assert got[key] == pytest.approx(value, rel=1e-6, abs=1e-12), key


def test_idf_totals_match_sellars_analytic_totals(capsys):
    from bev_mdo.config import load_config, resolve_disciplines, run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    config = load_config(SELLAR / "sellar_idf.yaml")
    form = build_formulation(run_settings(config), InProcessEvaluator(resolve_disciplines(config)))
    s1, s2 = form.coupling_scale  # consistency h = (target - computed) / scale
    rep = _report(capsys, SELLAR / "sellar_idf.yaml")
    assert rep["formulation"] == "idf" and rep["ok"], rep
    p = rep["point"]
    z1, z2, x, t1, t2 = (p[k] for k in ("z1", "z2", "x", "y1", "y2"))
    names = ("z1", "z2", "x", "y1", "y2")
    dy1 = [2 * z1, 1.0, 1.0, 0.0, -0.2]            # y1 computed from the targets
    dy2 = [1.0, 1.0, 0.0, 0.5 / np.sqrt(t1), 0.0]   # y2 computed from the targets
    want = {"obj": [0.0, 1.0, 2 * x, 1.0, -np.exp(-t2)], "y1 >= 3.16": dy1, "y2 <= 24": dy2,
            "y1 consistency": [(float(k == 3) - d) / s1 for k, d in enumerate(dy1)],
            "y2 consistency": [(float(k == 4) - d) / s2 for k, d in enumerate(dy2)]}
    got = _totals(rep)
    for of, row in want.items():
        for v, value in zip(names, row):
            assert got[(of, v)] == pytest.approx(value, rel=1e-6, abs=1e-12), (of, v)


def test_a_wrong_partial_shows_as_a_disagreeing_total(capsys, monkeypatch):
    """The check can fail: a discipline partial off by 10 % makes the assembled totals disagree."""
    import sys

    sys.path.insert(0, str(SELLAR))
    import sellar_disciplines

    right = sellar_disciplines.SellarDis1.compute_partials

    def wrong(self, inputs):
        p = right(self, inputs)
        p[("y1", "z1")] = 1.1 * p[("y1", "z1")]
        return p

    monkeypatch.setattr(sellar_disciplines.SellarDis1, "compute_partials", wrong)
    assert main(["check-totals", str(SELLAR / "sellar_mdf.yaml"), "--transport", "inprocess"]) == 1
    out = capsys.readouterr().out
    assert "DISAGREE" in out and "some totals disagree" in out


def test_idf_with_bounded_couplings_is_checked_at_the_point_its_gradient_evaluated(capsys):
    """propane IDF: scaling's round trip moved a bounded coupling by 4.4e-16, the check looked the other
    point up in the cache and stopped with 'the analysis of the design failed: not evaluated' (exit 2)."""
    rep = _report(capsys, REPO / "examples" / "propane" / "propane_idf.yaml")
    assert rep["formulation"] == "idf" and rep["ok"] and not rep["error"], rep["error"]


def test_a_constraint_bound_far_from_its_value_keeps_its_digits(capsys, tmp_path):
    # y2 <= 1e9 with y2 ~ 10: the differences of g = (y2 - 1e9) / 1e9 lost all but 3-4 digits in both
    # the optimiser's gradient and the command's own differences, and the command said DISAGREE.
    text = (SELLAR / "sellar_mdf.yaml").read_text().replace("y2: {upper: 24}", "y2: {upper: 1000000000}")
    (tmp_path / "far.yaml").write_text(text.replace("name: sellar_mdf", f"search_path: [{SELLAR}]\nname: far"))
    rep = _report(capsys, tmp_path / "far.yaml")
    assert rep["ok"], [r for r in rep["rows"] if not r["ok"]]
    want = _mdf_analytic(*(rep["point"][v] for v in VARS))
    got = _totals(rep)
    for v in VARS:
        assert got[("y2 <= 1e+09", v)] == pytest.approx(want[("y2 <= 24", v)], rel=1e-6, abs=1e-12), v


def test_a_point_the_scaled_variables_cannot_hold_is_refused(capsys, tmp_path):
    # bounds +-1e20: the optimiser's variable (x + 1e20) / 2e20 rounds x = 1 to 0, and the table said "at x=0"
    text = (SELLAR / "sellar_mdf.yaml").read_text().replace("x: {lower: 0, upper: 10, initial: 1}",
                                                            "x: {lower: -1.0e+20, upper: 1.0e+20, initial: 0}")
    (tmp_path / "wide.yaml").write_text(text.replace("name: sellar_mdf", f"search_path: [{SELLAR}]\nname: wide"))
    code = main(["check-totals", str(tmp_path / "wide.yaml"), "--transport", "inprocess", "--at", "x=1"])
    err = capsys.readouterr().err
    assert code == 2 and "x: 1 is lost to rounding in the optimiser's scaled variable" in err, err


def test_one_sided_differences_and_zero_rows_are_said(capsys):
    """A sensitivity trial: at a bound the header said 'against central differences' while the variable was
    differenced one-sided; a total of 3.8e-17 beside an FD of 0 printed 'rel err 1' next to 'ok'."""
    leaf = REPO / "config" / "leaf_nedc.yaml"
    assert main(["check-totals", str(leaf), "--at", "battery_kwh=20", "--transport", "inprocess"]) == 0
    out = capsys.readouterr().out
    assert "; one-sided for battery_kwh: a bound or a failed point within a step" in out, out
    row = next(line for line in out.splitlines() if "motor_speed_max_rad_s" in line and "battery_kwh" in line)
    assert row.split()[-2:] == ["-", "ok"], row
    assert main(["check-totals", str(leaf), "--transport", "inprocess", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["one_sided"] == []



def test_each_total_is_given_in_its_units(capsys, tmp_path):
    """The rows named what was differentiated but not in which units (check-partials says ' Wh/km per kW')."""
    leaf = REPO / "config" / "leaf_nedc.yaml"
    idf = {(r["of"], r["wrt"]): r["unit"] for r in _report(capsys, leaf, "--formulation", "idf")["rows"]}
    assert idf[("energy_wh_per_km", "motor_kw")] == "Wh/km per kW"
    assert idf[("range_km >= 170", "battery_kwh")] == "km per kWh"
    assert idf[("energy_wh_per_km", "gear_ratio")] == "Wh/km"  # per a ratio
    assert idf[("vehicle_mass_kg consistency", "motor_kw")] == "1 per kW"  # normalised by its coupling's scale
    assert idf[("vehicle_mass_kg consistency", "gear_ratio")] == "1"
    assert main(["check-totals", str(leaf), "--transport", "inprocess"]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.split()[:2] == ["energy_wh_per_km", "motor_kw"])
    assert row.split()[2:5] == ["Wh/km", "per", "kW"], row
    # a model parameter made a design variable: its unit from the parameter's spec (it read 'Wh/km')
    text = leaf.read_text().replace("  design_variables:\n", "  design_variables:\n    drag_area_m2: {lower: 0.5, upper: 0.8, initial: 0.6412}\n", 1)
    cfg = tmp_path / "cda.yaml"
    cfg.write_text(text.replace("battery_kwh: 24}", "battery_kwh: 24, drag_area_m2: 0.6412}"))
    units = {(r["of"], r["wrt"]): r["unit"] for r in _report(capsys, cfg)["rows"]}
    assert units[("energy_wh_per_km", "drag_area_m2")] == "Wh/km per m^2"


EDGE = """
import numpy as np


class Edge:
    name = "edge"
    inputs = ("a", "b")
    outputs = ("y",)
    units = {"a": "1", "b": "1", "y": "1"}

    def compute(self, inputs):
        a, b = np.asarray(inputs["a"], float), np.asarray(inputs["b"], float)
        if np.any(a > 1.0):
            raise RuntimeError("melts above a = 1")
        if np.any((b != 0.5) & (np.abs(b - 0.5) < 1e-3)):
            raise RuntimeError("b next to 0.5 but not 0.5")
        return {"y": a * a + 3.0 * b}

    def compute_partials(self, inputs):
        a = np.asarray(inputs["a"], float)
        return {("y", "a"): 2.0 * a, ("y", "b"): np.full(a.shape, 3.0)}
"""


def test_a_failed_side_is_left_out_not_differenced_as_its_penalty(capsys, tmp_path):
    """A formulation trial: at a = 1 where the + side fails, the fd column showed 2.27e+15 (the failure's penalty
    over h) against the right total, 'DISAGREE'. The failed side is left out (one-sided from the point); a total
    whose two sides both fail has no fd and is not 'ok'; a design that itself fails exits 1, as the docs say."""
    (tmp_path / "edge.py").write_text(EDGE, encoding="utf-8")
    cfg = tmp_path / "edge.yaml"
    cfg.write_text("name: edge\ndisciplines: [{name: edge, class: 'edge:Edge'}]\nproblem:\n  objective: y\n"
                   "  design_variables:\n    a: {lower: 0, upper: 2, initial: 1}\n    b: {lower: 0, upper: 1, initial: 0.25}\n",
                   encoding="utf-8")
    rep = _report(capsys, cfg, "--at", "a=1,b=0.25")
    assert rep["ok"] and rep["one_sided"] == ["a"] and "1 finite-difference points failed (left out)" in rep["error"]
    assert _totals(rep)[("y", "a")] == pytest.approx(2.0, rel=1e-12)
    assert {(r["of"], r["wrt"]): r["fd"] for r in rep["rows"]}[("y", "a")] == pytest.approx(2.0, rel=1e-5)
    rep = _report(capsys, cfg, "--at", "a=0.5,b=0.5")  # both sides of b fail: no difference, exit 1
    row = next(r for r in rep["rows"] if r["wrt"] == "b")
    assert not rep["ok"] and not row["ok"] and row["fd"] is None and row["total"] == pytest.approx(3.0)  # NaN: null
    assert main(["check-totals", str(cfg), "--at", "a=0.5,b=0.5", "--transport", "inprocess"]) == 1
    out = capsys.readouterr().out
    assert "no fd: no side left" in out and "1 total has no finite difference (a failed point on one side" in out
    assert out.rstrip().endswith("; none disagrees")
    assert main(["check-totals", str(cfg), "--at", "a=1.5,b=0.25", "--transport", "inprocess"]) == 1
    assert "the analysis of the design failed" in capsys.readouterr().err
