"""Analytic partials: assembled totals (MDF solve, IDF), mixing with FD, validation, check-partials."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.discipline import run_discipline
from bev_mdo.mdo.driver import build_formulation, run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.vectors import ShapeError, wrap


ROOT = Path(__file__).resolve().parents[2]
SELLAR = ROOT / "examples" / "sellar_vector.yaml"
LEAF = ROOT / "config" / "leaf_nedc.yaml"


def _config(path, derivatives, **problem):
    raw = yaml.safe_load(Path(path).read_text())
    raw.setdefault("optimizer", {})["derivatives"] = derivatives
    raw["problem"].update(problem)
    return load_config(raw)


def _gradients(cfg, formulation, u=None, evaluator=None):
    ev = evaluator or InProcessEvaluator(resolve_disciplines(cfg))
    form = build_formulation(cfg, ev, formulation)
    u = form.to_u(form.x0) if u is None else u
    return form.gradients(u), form


def _central_fd(cfg, formulation, u, h=1e-6):
    """Reference: central differences of the formulation's f, g, h (in scaled u)."""
    ev = InProcessEvaluator(resolve_disciplines(cfg))
    form = build_formulation(cfg, ev, formulation)
    cols = []
    for j in range(len(u)):
        e = np.zeros(len(u))
        e[j] = h
        fp, gp, hp = form.evaluate_batch(form.to_x(u + e)[None])
        fm, gm, hm = form.evaluate_batch(form.to_x(u - e)[None])
        cols.append(np.concatenate([fp - fm, gp[0] - gm[0], hp[0] - hm[0]]) / (2 * h))
    return np.array(cols).T


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
@pytest.mark.parametrize("path, sized", [(SELLAR, False), (LEAF, False), (LEAF, True)])
def test_assembled_gradients_equal_central_differences(path, sized, formulation):
    """Sellar (a loop, vectors), the BEV graph (feed-forward, analytic + FD disciplines mixed) and
    the battery-sized BEV graph (a loop through battery_sizing)."""
    extra = {"battery_sized_for_range": True} if sized else {}
    cfg = _config(path, "analytic", **extra)
    (df, dg, dh), form = _gradients(cfg, formulation)
    assert form.derivatives == "analytic"
    u = form.to_u(form.x0)
    ref = _central_fd(_config(path, "fd", **extra), formulation, u)
    got = np.vstack([df[None], dg, dh])
    np.testing.assert_allclose(got, ref, rtol=2e-5, atol=2e-6 * max(1.0, np.abs(ref).max()))


def test_disciplines_without_partials_are_mixed_in_by_finite_differences():
    from vector_toys import NoPartials

    cfg = _config(SELLAR, "analytic")
    all_analytic, _ = _gradients(cfg, "mdf")
    discs = resolve_disciplines(cfg)
    mixed = [wrap(NoPartials(d.inner)) if d.name == "sellar_dis2" else d for d in discs]
    ev = InProcessEvaluator(mixed)
    assert [ev.specs[n].partials for n in ev.specs] == [True, False, True]
    got, form = _gradients(cfg, "mdf", evaluator=ev)
    assert form.derivatives == "analytic"
    for a, b in zip(all_analytic, got):
        np.testing.assert_allclose(b, a, rtol=1e-5, atol=1e-7)
    # the FD of sellar_dis2 alone: its 3 inputs + its base point (it sits in a loop)
    assert ev.counts["sellar_dis2"] > ev.counts["sellar_functions"]


def test_auto_picks_analytic_only_when_every_discipline_has_partials():
    from vector_toys import NoPartials

    cfg = load_config(SELLAR)
    assert cfg["optimizer"]["derivatives"] == "auto"
    _, form = _gradients(cfg, "mdf")
    assert form.derivatives == "analytic"
    discs = resolve_disciplines(cfg)
    ev = InProcessEvaluator([wrap(NoPartials(d.inner)) if d.name == "sellar_dis2" else d for d in discs])
    _, form = _gradients(cfg, "mdf", evaluator=ev)
    assert form.derivatives == "fd"
    _, form = _gradients(load_config(LEAF), "mdf")  # energy and acceleration have no partials
    assert form.derivatives == "fd"


def test_bev_default_problem_same_optimum_with_fewer_analyses():
    a = run_optimization(c := _config(LEAF, "analytic"), InProcessEvaluator(resolve_disciplines(c)))
    f = run_optimization(c := _config(LEAF, "fd"), InProcessEvaluator(resolve_disciplines(c)))
    assert a.feasible and f.feasible
    for k in f.design:
        assert a.design[k] == pytest.approx(f.design[k], rel=1e-6), k
    assert a.objective == pytest.approx(f.objective, rel=1e-9)
    assert a.mda_evaluations < f.mda_evaluations
    # vehicle_mass, range, motor_speed and cost give analytic partials: evaluated once per analysis
    assert a.discipline_evaluations["cost"] == a.mda_evaluations


def test_a_partial_of_the_wrong_shape_is_one_line_naming_the_discipline():
    from vector_toys import WrongPartialShape

    d = wrap(WrongPartialShape())
    with pytest.raises(ShapeError, match=r"discipline 'sellar_dis1': partial dy1/dz has shape \(1, 2\), "
                                         r"expected \(1, 1, 2\)"):
        run_discipline(d, {"z[0]": [1.0], "z[1]": [0.0], "x": [0.0], "y2": [1.0]}, partials=True)


def test_partials_of_failed_points_are_nan_and_of_good_points_exact():
    from examples.sellar_vector import SellarDis2

    res = run_discipline(wrap(SellarDis2()), {"z[0]": [1.0, np.nan], "z[1]": [0.0, 0.0], "y1": [4.0, 4.0]},
                         partials=True)
    assert res.ok.tolist() == [True, False]
    p = res.extra["partials"]
    assert p[("y2", "y1")][0] == pytest.approx(0.25) and np.isnan(p[("y2", "y1")][1])


def _sellar_with(cls):
    raw = yaml.safe_load(SELLAR.read_text())
    raw["disciplines"][0]["class"] = f"vector_toys:{cls}"
    return load_config(raw)


def test_check_partials_reports_a_wrong_partial_and_passes_correct_ones():
    from bev_mdo.cli.check_partials import check

    good = check(load_config(SELLAR), "z=1,x=2")
    assert good["ok"] and all(d["partials"] == "analytic" for d in good["disciplines"])
    bad = check(_sellar_with("WrongPartial"), "z=1,x=2")
    assert not bad["ok"]
    (dis1,) = [d for d in bad["disciplines"] if d["mismatches"]]
    assert dis1["discipline"] == "sellar_dis1"
    assert [(m["output"], m["input"]) for m in dis1["mismatches"]] == [("y1", "z[0]")]
    assert dis1["mismatches"][0]["analytic"] == pytest.approx(4.0)
    assert dis1["mismatches"][0]["fd"] == pytest.approx(2.0, rel=1e-6)


def test_check_partials_cli_exit_status_and_one_line_per_mismatch(tmp_path, capsys, monkeypatch):
    from bev_mdo.cli import main

    raw = yaml.safe_load(SELLAR.read_text())
    raw["disciplines"][0]["class"] = "vector_toys:WrongPartial"
    cfg = tmp_path / "bad.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    assert main(["check-partials", str(SELLAR), "--at", "z[0]=1,x=2"]) == 0
    capsys.readouterr()
    assert main(["check-partials", str(cfg), "--at", "z[0]=1,x=2"]) == 1
    out = capsys.readouterr().out
    assert "sellar_dis1: dy1/dz[0] analytic 4 but finite differences 2" in out
    assert "(each partial in the run's units, per unit of the input as its producer declares it)" in out
    from bev_mdo.cli.check_partials import _per  # a derivatives trial: 500 against 0.5, no unit said (kN per m)

    assert (_per({"u": "kN", "v[0]": "m"}, "u", "v[0]"), _per({"y1": "1", "z[0]": "1"}, "y1", "z[0]")) == (" kN per m", "")
    assert main(["check-partials", str(SELLAR), "--at", "w=1"]) == 2
    assert "w" in capsys.readouterr().err
    assert main(["check-partials", str(LEAF)]) == 0  # the built-in BEV partials


def test_compute_partials_that_raises_is_one_line_naming_the_discipline():
    from examples.sellar_vector import SellarDis2

    class Broken(SellarDis2):
        def compute_partials(self, inputs):
            raise KeyError("y3")

    with pytest.raises(ShapeError, match=r"discipline 'sellar_dis2': compute_partials\(\) raised KeyError: 'y3'"):
        run_discipline(wrap(Broken()), {"z[0]": [1.0], "z[1]": [0.0], "y1": [4.0]}, partials=True)
