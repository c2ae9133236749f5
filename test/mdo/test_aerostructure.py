"""GEMSEO's aerostructure toy problem (examples/aerostructure/) through the user-discipline interface
only: the disciplines against GEMSEO's implementation, bev_mdo's MDA against GEMSEO's MDA, and MDF
and IDF in process reaching the optimum of GEMSEO's example (maximise the range subject to
reserve_fact <= 0.5 and lift = 0.5) and of GEMSEO's own test (the range minimised).

Reference numbers were produced with GEMSEO 6.3.3 (``gemseo.problems.mdo.aerostructure``), which is
not a dependency of bev_mdo: ``Aerodynamics/Structure/Mission.execute`` at the inputs below,
``create_mda("MDAGaussSeidel", ..., tolerance=1e-14)`` for the analyses, and ``create_scenario`` with
MDF and IDF and SLSQP (ftol/xtol 1e-14) for the optima (docs/aerostructure.md).

Tolerances. Disciplines: 1e-12 relative (the same arithmetic, re-typed). MDA: 1e-10 relative (both
converge the linear forces <-> displ loop to 1e-13/1e-14). Optima: the couplings are linear in the
design, so the optimum has a closed form (two active linear constraints and a bound); bev_mdo is
held to 1e-9 relative of it on the range and 1e-7 on the design, tighter than GEMSEO's own results
(its MDF optimum is 6e-9 above it, because it violates reserve_fact <= 0.5 by 3.2e-5, inside
GEMSEO's ineq_tolerance 1e-4; its IDF optimum is 2e-10 above). GEMSEO's numbers are checked to the
closed form at the tolerance they reach.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from bev_mdo.config import resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA
from bev_mdo.testing import example_config

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "aerostructure"
sys.path.insert(0, str(EXAMPLE))
import aerostructure_disciplines as aero  # noqa: E402

# discipline inputs -> GEMSEO 6.3.3's outputs (aerodynamics, structure, mission on the computed values)
POINTS = [
    ({"sweep": 25.0, "thick_airfoils": 15.0, "thick_panels": 3.0, "displ": -700.0, "forces": 400.0},
     {"drag": 321.00048225308643, "forces": 393.0, "lift": 0.476,
      "mass": 280301.33959190676, "reserve_fact": 2.0, "displ": -741.0, "range": 4232.1990126711635}),
    ({"sweep": 10.0, "thick_airfoils": 5.0, "thick_panels": 20.0, "displ": 100.0, "forces": -200.0},
     {"drag": -17.999922839506173, "forces": 81.0, "lift": -0.063,
      "mass": 162000.08573388204, "reserve_fact": -115.0, "displ": 480.0, "range": 17284.01556153818}),
    ({"sweep": 35.0, "thick_airfoils": 25.0, "thick_panels": 1.0, "displ": -300.0, "forces": 700.0},
     {"drag": 200.0009452160494, "forces": 415.0, "lift": 0.21333333333333335,
      "mass": 340103.675840192, "reserve_fact": 14.0, "displ": -1327.0, "range": 2509.0269851465678}),
]
# GEMSEO's MDAGaussSeidel (tolerance 1e-14): the start design, and GEMSEO's test's x_ref
MDAS = [
    ({"sweep": 25.0, "thick_airfoils": 15.0, "thick_panels": 3.0},
     {"drag": 339.0004822530859, "forces": 401.9999999999998, "lift": 0.5059999999999991,
      "mass": 280701.3395919067, "reserve_fact": 2.1999999999999815, "displ": -744.9999999999995,
      "range": 4253.982535408962}),
    ({"sweep": 27.24051915830433, "thick_airfoils": 25.0, "thick_panels": 20.0},
     {"drag": 373.55346913258654, "forces": 424.1816398662023, "lift": 0.5000016673299648,
      "mass": 286838.06097350793, "reserve_fact": -104.30339348829276, "displ": -733.882241415796,
      "range": 3733.1194596682076}),
]
GEMSEO_MAX = {"mdf": 4509.505474875261, "idf": 4509.505447886527}   # SLSQP, maximise (GEMSEO's example)
GEMSEO_MIN = {"mdf": 3733.12011213048, "idf": 3733.120237303767}    # SLSQP, minimise (GEMSEO's test)
# closed form of the minimised problem: thick_airfoils = 25 and thick_panels = 20 on their upper
# bounds, lift = 0.5 gives sweep = (1500 + 10 tp - (0.2 + 4/3) ta) / 61
MIN_SWEEP = (1500.0 + 10.0 * 20.0 - (0.2 + 4.0 / 3.0) * 25.0) / 61.0
MIN_RANGE = 3733.120259933678

CLASSES = (aero.Aerodynamics, aero.Structure, aero.Mission)


def _config(formulation="mdf", **changes):
    return example_config(EXAMPLE / f"aerostructure_{formulation}.yaml", **changes)


def _run(config, **kw):
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


@pytest.mark.parametrize("inputs,expected", POINTS, ids=["start", "low", "high"])
def test_every_discipline_output_equals_gemseo_to_1e12(inputs, expected):
    values = {k: np.array([v]) for k, v in inputs.items()}
    a = aero.Aerodynamics().compute(values)
    s = aero.Structure().compute(values)
    m = aero.Mission().compute({"lift": a["lift"], "mass": s["mass"], "drag": a["drag"]})
    got = {**a, **s, **m}
    assert set(got) == set(expected)
    for name, value in expected.items():
        assert got[name].shape == (1,)
        np.testing.assert_allclose(got[name], [value], rtol=1e-12, atol=1e-14, err_msg=name)


def test_a_batch_of_points_equals_the_points_one_by_one():
    batch = {k: np.array([p[0][k] for p in POINTS]) for k in POINTS[0][0]}
    batch.update(lift=np.array([0.4, 0.5, 0.6]), mass=np.array([2.5e5, 2.8e5, 3e5]), drag=np.array([300., 320, 340]))
    for cls in CLASSES:
        d = cls()
        whole = d.compute({k: batch[k] for k in d.inputs})
        for i in range(3):
            one = d.compute({k: batch[k][i:i + 1] for k in d.inputs})
            for name in whole:
                np.testing.assert_array_equal(whole[name][i:i + 1], one[name])


@pytest.mark.parametrize("design,expected", MDAS, ids=["start", "gemseo_x_ref"])
def test_the_bev_mdo_mda_of_the_user_disciplines_equals_gemseos_mda(design, expected):
    config = _config()
    mda = MDA(InProcessEvaluator(resolve_disciplines(config)), tolerance=1e-13, max_iterations=200)
    assert mda.graph.cycles and sorted(mda.graph.cycles[0]) == ["aerodynamics", "structure"]
    res = mda.run({k: [v] for k, v in design.items()})
    assert res.ok.all(), res.errors
    for name, value in expected.items():
        assert res.values[name][0] == pytest.approx(value, rel=1e-10), name


def test_the_closed_form_optimum_and_gemseos_numbers_agree():
    """The example's OPTIMUM is the solution of lift = 0.5 and reserve_fact = 0.5 at thick_airfoils = 5
    (the MDA of it, here); GEMSEO's SLSQP results sit within 1e-8 (MDF) and 1e-9 (IDF) of it."""
    mda = MDA(InProcessEvaluator(resolve_disciplines(_config())), tolerance=1e-14, max_iterations=200)
    res = mda.run({k: [v] for k, v in aero.OPTIMUM.items()})
    assert res.values["lift"][0] == pytest.approx(0.5, abs=1e-13)
    assert res.values["reserve_fact"][0] == pytest.approx(0.5, abs=1e-11)
    assert res.values["range"][0] == pytest.approx(aero.OPTIMUM_RANGE, rel=1e-13)
    assert GEMSEO_MAX["mdf"] == pytest.approx(aero.OPTIMUM_RANGE, rel=1e-8)
    assert GEMSEO_MAX["idf"] == pytest.approx(aero.OPTIMUM_RANGE, rel=1e-9)
    assert GEMSEO_MIN["mdf"] == pytest.approx(MIN_RANGE, rel=1e-7)
    assert GEMSEO_MIN["idf"] == pytest.approx(MIN_RANGE, rel=1e-8)


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
@pytest.mark.parametrize("derivatives", ["analytic", "fd"])
def test_slsqp_reaches_the_maximum_range(formulation, derivatives):
    """GEMSEO's example problem from GEMSEO's start design (range 4253.98, infeasible)."""
    res = _run(_config(formulation, **{"optimizer.derivatives": derivatives}))
    assert res.feasible and res.formulation == formulation and res.maximize
    assert res.objective == pytest.approx(aero.OPTIMUM_RANGE, rel=1e-9)
    for name, value in aero.OPTIMUM.items():
        assert res.design[name] == pytest.approx(value, rel=1e-7), name
    assert res.outputs["lift"] == pytest.approx(0.5, abs=1e-9)
    assert res.outputs["reserve_fact"] == pytest.approx(0.5, abs=1e-8)
    assert res.history[0]["objective"] == pytest.approx(MDAS[0][1]["range"], rel=1e-10)


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
def test_slsqp_reaches_gemseos_test_optimum_when_the_range_is_minimised(formulation):
    """GEMSEO's unit test minimises the range (x_ref = (25, 20, 27.2405), f_ref 3733.1202599):
    the same config with ``maximize: false`` must go the other way, to both thicknesses' upper bounds."""
    res = _run(_config(formulation, **{"problem.objective": "range"}))
    assert res.feasible and not res.maximize
    assert res.objective == pytest.approx(MIN_RANGE, rel=1e-9)
    assert res.design["thick_airfoils"] == pytest.approx(25.0, abs=1e-9)
    assert res.design["thick_panels"] == pytest.approx(20.0, abs=1e-9)
    assert res.design["sweep"] == pytest.approx(MIN_SWEEP, rel=1e-8)


@pytest.mark.parametrize("formulation,optimizer,rel", [("mdf", "COBYQA", 1e-9), ("mdf", "COBYLA", 1e-9),
                                                       ("mdf", "trust-constr", 1e-9), ("idf", "COBYQA", 2e-8),
                                                       ("idf", "trust-constr", 1e-9)])
def test_other_optimisers_that_reach_the_maximum(formulation, optimizer, rel):
    """docs/aerostructure.md: these reach it too (IDF with COBYQA to 1e-8: its end point keeps a
    consistency violation of 9e-9 that buys 9e-9 of range). IDF with COBYLA did not on
    the development host (it stopped 2.6 % short, docs/aerostructure.md); not asserted either way."""
    res = _run(_config(formulation), optimizer=optimizer)
    assert res.feasible and res.optimizer == optimizer and res.verdict == "optimum"
    assert res.objective == pytest.approx(aero.OPTIMUM_RANGE, rel=rel)
    assert res.design["thick_airfoils"] == pytest.approx(5.0, abs=1e-6)


@pytest.mark.parametrize("at", ["", "thick_airfoils=5,thick_panels=3.2255892255892404,sweep=24.99326599326595",
                                "thick_airfoils=25,thick_panels=20,sweep=10"])
def test_check_partials_agrees_with_finite_differences(at):
    from bev_mdo.cli.check_partials import check

    report = check(_config(), at=at)
    assert report["ok"], [m for d in report["disciplines"] for m in d["mismatches"]][:5]
    assert [d["partials"] for d in report["disciplines"]] == ["analytic"] * 3
    assert sum(d["entries"] for d in report["disciplines"]) == 21
