"""Sobieski's SSBJ (examples/ssbj/) through the user-discipline interface only: the disciplines
against GEMSEO's implementation, the MDA of bev_mdo against GEMSEO's MDA, and MDF and IDF in
process reaching the reference optimum (over ROS: test/ros/test_ssbj_ros.py).

Reference numbers were produced with GEMSEO 6.3.3 (``gemseo.problems.mdo.sobieski``), which is
not a dependency of bev_mdo: ``SobieskiStructure/Aerodynamics/Propulsion/Mission.execute`` at the
inputs below, and ``create_mda("MDAGaussSeidel", ..., tolerance=1e-14)`` for the analyses.
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

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "ssbj"
sys.path.insert(0, str(EXAMPLE))
import ssbj_disciplines as ssbj  # noqa: E402

# discipline inputs (x_shared, x_1, x_2, x_3, couplings) -> GEMSEO 6.3.3's outputs
DEFAULT_INPUTS = {  # GEMSEO's SobieskiProblem.get_default_inputs()
    "x_shared": [0.05, 45000.0, 1.6, 5.5, 55.0, 1000.0], "x_1": [0.25, 1.0], "x_2": 1.0, "x_3": 0.5,
    "y_21": 50606.9741711, "y_31": 6354.32430691, "y_32": 0.50279625, "y_23": 12562.01206488,
    "y_14": [50606.9741711, 7306.20262124], "y_24": 4.15006276, "y_34": 1.10754577, "y_12": [50606.9742, 0.95]}
DEFAULT_OUTPUTS = {
    "y_12": [50606.97417113064, 0.95], "y_14": [50606.97417113064, 7306.202621238479],
    "g_1": [0.035, -0.006666666666666599, -0.02750000000000008, -0.040000000000000036, -0.04833333333333334,
            -0.09000000000000008, -0.1499999999999999],
    "y_21": 50606.9742, "y_23": 12194.409111328641, "y_24": 4.150014464660364, "g_2": -0.040000000000000036,
    "y_31": 6555.684592352268, "y_32": 0.5179591745679898, "y_34": 1.107545774255054,
    "g_3": [-0.9820408254320102, -0.01795917456798979, 0.16206032335992582, -0.020000000000000018],
    "y_4": 535.7884501700407}
HIGH_INPUTS = {  # a random design (above the 36089 ft tropopause), arbitrary couplings
    "x_shared": [0.017530291379231934, 42993.80820709422, 1.5916205192563335, 3.4584334878224716,
                 62.037314542276434, 613.6720199214034],
    "x_1": [0.1256947501430873, 0.8684052532980499], "x_2": 1.1506372326031984, "x_3": 0.623945832457931,
    "y_21": 42000.0, "y_31": 7000.0, "y_32": 0.8, "y_23": 9000.0, "y_14": [42000.0, 12000.0], "y_24": 6.5,
    "y_34": 1.05, "y_12": [42000.0, 0.97]}
HIGH_OUTPUTS = {
    "y_12": [37063.74262899, 1.010323085840936], "y_14": [37063.74262899, 3127.8441065756488],
    "g_1": [-0.12484050023706739, -0.05006519873791104, -0.03636322352088284, -0.03572145456108222,
            -0.03845169865888831, -0.02967691415906404, -0.21032308584093595],
    "y_21": 42000.0, "y_23": 5467.820246717473, "y_24": 7.681305914402379, "g_2": -0.09000000000000008,
    "y_31": 3660.7897846670185, "y_32": 0.2973732843332096, "y_34": 1.151260492436008,
    "g_3": [-1.2026267156667905, 0.2026267156667904, 0.3211638521719784, 0.08049291094444277],
    "y_4": 1900.1781679515027}
LOW_INPUTS = {  # below the tropopause (the other branch of the atmosphere and of the range)
    "x_shared": [0.07, 32000.0, 1.7, 7.0, 45.0, 1300.0], "x_1": [0.3, 1.1], "x_2": 0.9, "x_3": 0.3,
    "y_21": 48000.0, "y_31": 5000.0, "y_32": 0.6, "y_23": 11000.0, "y_14": [48000.0, 9000.0], "y_24": 5.5,
    "y_34": 1.2, "y_12": [48000.0, 1.02]}
LOW_OUTPUTS = {
    "y_12": [60183.535375408974, 0.879557110124918], "y_14": [60183.535375408974, 11760.211273756713],
    "g_1": [-0.4621485576923072, -0.2553281339031338, -0.1829570112179486, -0.1494668461538461,
            -0.13127861467236468, -0.16044288987508204, -0.07955711012491795],
    "y_21": 48000.0, "y_23": 51800.25403415801, "y_24": 0.9266363822916379, "g_2": 0.010000000000000009,
    "y_31": 9750.107198489517, "y_32": 0.7559233466238402, "y_34": 1.311267217000827,
    "g_3": [-0.7440766533761598, -0.2559233466238402, -0.6535299887400753, -0.023937499999999945],
    "y_4": 944.4714127733395}

# GEMSEO's MDAGaussSeidel (tolerance 1e-14) at three designs: range and a few couplings
DESIGNS = {
    "initial": ({"x_shared": [0.05, 45000, 1.6, 5.5, 55, 1000], "x_1": [0.25, 1.0], "x_2": 1.0, "x_3": 0.5},
                {"y_4": 535.7821319229386, "y_21": 50607.0636190258, "y_23": 12194.409178632462,
                 "g_3[2]": 0.16206032335992582}),
    "bliss": ({"x_shared": [0.06, 60000, 1.4, 2.5, 70, 1500], "x_1": [0.38757, 0.75], "x_2": 0.75, "x_3": 0.15624},
              {"y_4": 3963.1737649884385, "y_21": 44757.27101200351, "y_23": 5553.786792877312,
               "g_3[2]": -3.037315762433046e-05}),
    "optimum": ({"x_shared": [0.06, 60000, 1.4, 2.5, 70, 1500], "x_1": [0.4, 0.75], "x_2": 0.75,
                 "x_3": 0.15624474564626545},
                {"y_4": 3963.3800122700973, "y_21": 44749.826882232635, "y_23": 5553.829929983666}),
}
PUBLISHED_RANGE = 3963.98      # BLISS (NASA/TM-1998-208715), as GEMSEO documents it (optimum_range)
OPTIMUM_RANGE = 3963.3800123   # the best feasible range of these equations (GEMSEO's own IDF: 3963.387,
                               # with constraint violations of up to 1.5e-6)

CLASSES = {"structure": ssbj.Structure, "aerodynamics": ssbj.Aerodynamics, "propulsion": ssbj.Propulsion,
           "mission": ssbj.Mission}


def _call(disc, point, n=1):
    """One discipline on a batch of n copies of ``point``."""
    inputs = {k: np.tile(np.asarray(point[k], dtype=float), (n, 1)) if k in disc.shapes
              else np.full(n, float(point[k])) for k in disc.inputs}
    return disc.compute(inputs)


@pytest.mark.parametrize("inputs,expected", [(DEFAULT_INPUTS, DEFAULT_OUTPUTS), (HIGH_INPUTS, HIGH_OUTPUTS),
                                             (LOW_INPUTS, LOW_OUTPUTS)], ids=["default", "high", "low"])
def test_every_discipline_output_equals_gemseo_to_1e12(inputs, expected):
    seen = set()
    for cls in CLASSES.values():
        out = _call(cls(), inputs)
        for name, value in out.items():
            assert np.shape(value) == ((1, cls.shapes[name]) if name in cls.shapes else (1,)), name
            np.testing.assert_allclose(np.ravel(value), np.ravel(expected[name]), rtol=1e-12, atol=1e-14,
                                       err_msg=f"{cls.name}: {name}")
            seen.add(name)
    assert seen == set(expected)


def test_a_batch_of_points_equals_the_points_one_by_one():
    rng = np.random.default_rng(7)
    lo = np.array([0.01, 30000, 1.4, 2.5, 40, 500]); hi = np.array([0.09, 60000, 1.8, 8.5, 70, 1500])
    n = 5
    batch = {"x_shared": lo + rng.random((n, 6)) * (hi - lo), "x_1": np.column_stack([rng.uniform(0.1, 0.4, n),
             rng.uniform(0.75, 1.25, n)]), "x_2": rng.uniform(0.75, 1.25, n), "x_3": rng.uniform(0.1, 1, n),
             "y_21": rng.uniform(3e4, 6e4, n), "y_31": rng.uniform(3e3, 1e4, n), "y_32": rng.uniform(0.4, 1.2, n),
             "y_23": rng.uniform(4e3, 2e4, n), "y_14": np.column_stack([rng.uniform(4e4, 6e4, n),
             rng.uniform(5e3, 2e4, n)]), "y_24": rng.uniform(3, 9, n), "y_34": rng.uniform(0.8, 1.3, n),
             "y_12": np.column_stack([rng.uniform(3e4, 6e4, n), rng.uniform(0.8, 1.1, n)])}
    for cls in CLASSES.values():
        d = cls()
        whole = d.compute({k: batch[k] for k in d.inputs})
        for i in range(n):
            one = d.compute({k: batch[k][i:i + 1] for k in d.inputs})
            for name in whole:
                np.testing.assert_allclose(whole[name][i:i + 1], one[name], rtol=1e-13, atol=1e-15)  # summation order


def _config(formulation="mdf", **changes):
    return example_config(EXAMPLE / f"ssbj_{formulation}.yaml", **changes)


def _flat(design):
    out = {}
    for k, v in design.items():
        if isinstance(v, (list, tuple)):
            out.update({f"{k}[{i}]": float(x) for i, x in enumerate(v)})
        else:
            out[k] = float(v)
    return out


@pytest.mark.parametrize("design", sorted(DESIGNS))
def test_the_bev_mdo_mda_of_the_user_disciplines_equals_gemseos_mda(design):
    config = _config()
    evaluator = InProcessEvaluator(resolve_disciplines(config))
    mda = MDA(evaluator, tolerance=1e-13, max_iterations=200)
    assert mda.graph.cycles and sorted(mda.graph.cycles[0]) == ["aerodynamics", "propulsion", "structure"]
    x, expected = DESIGNS[design]
    res = mda.run({k: [v] for k, v in _flat(x).items()})
    assert res.ok.all(), res.errors
    for name, value in expected.items():
        assert res.values[name][0] == pytest.approx(value, rel=1e-10, abs=1e-12), name


def _run(config, **kw):
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
@pytest.mark.parametrize("derivatives", ["analytic", "fd"])
def test_ssbj_reaches_the_reference_optimum_with_slsqp(formulation, derivatives):
    """From BLISS's initial design (range 535.8 nmi, infeasible): SLSQP, with the disciplines'
    analytic partials (the configs' default, ``derivatives: auto``) or finite differences.
    Tolerances: range 1e-3 nmi of the best feasible range of these equations, 2e-4 relative of
    the published BLISS range; every design variable 1e-6 relative of the BLISS design, but the
    taper ratio (at its upper bound 0.4 here, 0.38757 in BLISS: the range is flat in it, +0.2 nmi)
    and the throttle (1e-4 absolute)."""
    res = _run(_config(formulation, **{"optimizer.derivatives": derivatives}))
    assert res.feasible and res.formulation == formulation and res.maximize and res.verdict == "optimum"
    assert res.objective == pytest.approx(OPTIMUM_RANGE, abs=1e-3)
    assert res.objective == pytest.approx(PUBLISHED_RANGE, rel=2e-4)
    ref = _flat(ssbj.REFERENCE_DESIGN)
    for name, value in res.design.items():
        if name == "x_1[0]":
            assert value == pytest.approx(0.4, abs=1e-6)
        elif name == "x_3":
            assert value == pytest.approx(ref[name], abs=1e-4)
        else:
            assert value == pytest.approx(ref[name], rel=1e-6), name
    # the active constraints: pressure gradient and throttle
    assert res.outputs["g_2"] == pytest.approx(0.0, abs=1e-8)
    assert res.outputs["g_3[2]"] == pytest.approx(0.0, abs=1e-8)
    assert res.history[0]["objective"] == pytest.approx(DESIGNS["initial"][1]["y_4"], rel=1e-9)


@pytest.mark.parametrize("formulation,optimizer,rel", [("mdf", "COBYQA", 1e-6), ("idf", "trust-constr", 1e-6)])
def test_other_optimisers_that_reach_the_optimum(formulation, optimizer, rel):
    """docs/ssbj.md: MDF with COBYQA (no gradients) and IDF with trust-constr reach it too; the
    taper ratio, on which the range is flat, to 1e-4 only."""
    res = _run(_config(formulation), optimizer=optimizer)
    assert res.feasible and res.optimizer == optimizer and res.verdict == "optimum"
    assert res.objective == pytest.approx(OPTIMUM_RANGE, rel=rel)
    assert res.design["x_1[0]"] == pytest.approx(0.4, abs=1e-4)
    assert res.design["x_3"] == pytest.approx(0.1562447, abs=1e-6)


def test_mdf_with_trust_constr_does_not_reach_it_and_the_result_says_so():
    """docs/ssbj.md: trust-constr under MDF wanders infeasible for hundreds of iterations; capped at
    20 here, its result is an early feasible record far from the optimum, not the last iterate."""
    res = _run(_config("mdf", **{"optimizer.name": "trust-constr", "optimizer.options": {"maxiter": 20}}))
    assert res.optimizer == "trust-constr" and res.iterations == 20
    assert res.objective < 0.5 * OPTIMUM_RANGE
    assert not res.last_iterate and res.result_iteration < res.iterations
    assert res.verdict == "stopped before convergence" and not res.success


POINTS = {  # interior points (no polynomial input at its clip edge, where the derivative has a kink)
    "initial": "",
    "low": "x_shared[0]=0.045,x_shared[1]=33000,x_shared[2]=1.7,x_shared[3]=6.5,x_shared[4]=50,"
           "x_shared[5]=1100,x_1[0]=0.3,x_1[1]=1.1,x_2=0.9,x_3=0.6",
    "high": "x_shared[0]=0.065,x_shared[1]=52000,x_shared[2]=1.5,x_shared[3]=4,x_shared[4]=65,"
            "x_shared[5]=1300,x_1[0]=0.35,x_1[1]=0.8,x_2=0.8,x_3=0.2",
}


@pytest.mark.parametrize("point", sorted(POINTS))
def test_check_partials_agrees_with_finite_differences(point):
    from bev_mdo.cli.check_partials import check

    report = check(_config(), at=POINTS[point])
    assert report["ok"], [m for d in report["disciplines"] for m in d["mismatches"]][:5]
    assert [d["partials"] for d in report["disciplines"]] == ["analytic"] * 4
    assert sum(d["entries"] for d in report["disciplines"]) > 80


@pytest.mark.parametrize("formulation", ["mdf", "idf"])
def test_assembled_gradients_of_a_maximised_objective_equal_finite_differences(formulation):
    """The optimisers minimise -range: the gradient assembled from the partials must be of -range
    too (it was of +range, and SLSQP stalled at the start point)."""
    from bev_mdo.mdo.driver import build_formulation

    grads = {}
    for mode in ("analytic", "fd"):
        config = _config(formulation, **{"optimizer.derivatives": mode})
        form = build_formulation(config, InProcessEvaluator(resolve_disciplines(config)))
        assert form.derivatives == mode
        grads[mode] = form.gradients(form.to_u(form.x0))
    for a, b in zip(grads["analytic"], grads["fd"]):
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-4 * max(np.abs(b).max(initial=0), 1e-8))
    assert np.abs(grads["fd"][0]).max() > 1.0  # a gradient, not zeros
