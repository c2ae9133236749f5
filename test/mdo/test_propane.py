"""The propane combustion problem (examples/propane/) through the user-discipline interface only:
the disciplines against GEMSEO's implementation, and MDF and IDF in process reaching the known
optimum (obj = 0 where the four equilibrium residuals vanish).

Reference numbers were produced with GEMSEO 6.3.3 (``gemseo.problems.mdo.propane``), which is not a
dependency of bev_mdo: ``PropaneComb1/2/3.execute`` and ``PropaneReaction.execute`` at the points
below; GEMSEO's own unit tests pin the first ones too (y_1 = (1, 2), y_2 = (2, 0.05886036318), y_3 =
(38, 0.02943018159, 47.08829054) at x_shared = 1, and obj = -16.973665961 with every input 1).

Tolerances. Disciplines: 1e-12 relative (the same arithmetic, re-typed), or 1e-13 absolute for
the residuals near the optimum, differences of O(10) terms that cancel to 1e-6 (a last-bit
difference in one term is 2e-15 there). Optimum: the design is the
root of four equations in four unknowns (OPTIMUM, solved to 3e-15); obj is a sum of residuals that
the constraints hold >= 0, so obj can only go below 0 by violating them, and a result inside the
feasibility tolerance (1e-4, absolute here: the bounds are 0) may be up to ~1e-4 below 0. IDF with
SLSQP converges (6 iterations; obj 6e-11): held to 1e-8 on obj and 1e-7 on the design. MDF with
SLSQP does not converge (as in GEMSEO: 'Positive directional derivative for linesearch' after its
last step leaves the feasible set); its result is the best record within the tolerance, which
buys objective with violation (docs/propane.md): held to 2e-4 on obj and 2e-5 on the design; MDF with COBYLA converges (obj 7e-16) and is held to 1e-8 / 1e-7.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from bev_mdo.config import resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.testing import example_config

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "propane"
sys.path.insert(0, str(EXAMPLE))
import propane_disciplines as propane  # noqa: E402

# x_shared -> GEMSEO 6.3.3's y_1, y_2, y_3 and its reaction's outputs on them
CHAIN = [
    ([1.0, 1.0, 1.0, 1.0],
     {"y_1": [1.0, 2.0], "y_2": [2.0, 0.058860363180964305], "y_3": [38.0, 0.029430181590482152, 47.088290544771446],
      "f_2": -34.117720726361924, "f_6": -0.49254763314147654, "f_7": 0.3034324570965563, "f_9": 69.04661062160301,
      "obj": -34.73977471919616}),
    ([1.378887, 18.42681, 1.094798, 0.931214],  # GEMSEO's published optimum, rounded
     {"y_1": [1.3729090652259999, 1.621113], "y_2": [1.614084934774, 0.06316215235589157],
      "y_3": [3.1463800000000006, 0.053724490998195845, 29.703082643354083],
      "f_2": -1.1995782838170044e-06, "f_6": 1.2790970771447974e-07, "f_7": 4.7466018049391323e-07,
      "f_9": -8.296826079501329e-07, "obj": 1.4266910035587443e-06}),
    ([0.5, 5.0, 1.5, 0.2],
     {"y_1": [0.5249999999999999, 2.5], "y_2": [2.625, 0.02143786271763058],
      "y_3": [30.0, 0.0042875725435261155, 42.87572543526116],
      "f_2": -24.255013007804678, "f_6": -0.12117092548374697, "f_7": -0.20690870293642255,
      "f_9": 71.32314643212761, "obj": -46.74005379590277}),
    ([2.0, 30.0, 0.001, 2.0],
     {"y_1": [1.9996666666666667, 1.0], "y_2": [0.9998333333333334, 0.0913730964467005],
      "y_3": [-20.0, 0.182746192893401, 18.274619289340098],
      "f_2": 20.543467851099834, "f_6": -1.4120034214144719, "f_7": 0.9591043803629924,
      "f_9": -40.54382821761635, "obj": 20.453259407567998}),
]
# the reaction alone at given couplings (the first is GEMSEO's unit test: obj -16.973665961010276)
REACTION = [
    ({"x_shared": [1.0] * 4, "y_1": [1.0] * 2, "y_2": [1.0] * 2, "y_3": [1.0] * 3},
     {"f_2": 1.0, "f_6": 5.324555320336759, "f_7": 5.324555320336759, "f_9": 5.324555320336759,
      "obj": -16.973665961010276}),
    ({"x_shared": [1.2, 10.0, 0.7, 1.1], "y_1": [1.5, 0.4], "y_2": [2.5, 0.3], "y_3": [4.0, 2.0, 12.0]},
     {"f_2": -3.6999999999999993, "f_6": 0.6254033307585165, "f_7": -0.07147019428269719,
      "f_9": -0.8735462188411693, "obj": 4.01961308236535}),
]
COMBS = (propane.PropaneComb1, propane.PropaneComb2, propane.PropaneComb3)


def _config(formulation="mdf", **changes):
    return example_config(EXAMPLE / f"propane_{formulation}.yaml", **changes)


def _run(config, **kw):
    return run_optimization(config, InProcessEvaluator(resolve_disciplines(config)), **kw)


def _batch(values):
    return {k: np.atleast_2d(np.asarray(v, dtype=float)) for k, v in values.items()}


@pytest.mark.parametrize("x,expected", CHAIN, ids=["ones", "optimum", "mid", "corner"])
def test_the_chain_equals_gemseo_to_1e12(x, expected):
    values = {"x_shared": np.array([x])}
    for cls in COMBS:
        values.update(cls().compute(values))
    values.update(propane.PropaneReaction().compute(values))
    for name, value in expected.items():
        np.testing.assert_allclose(np.ravel(values[name]), np.ravel(value), rtol=1e-12, atol=1e-13, err_msg=name)


@pytest.mark.parametrize("inputs,expected", REACTION, ids=["gemseo_unit_test", "off_equilibrium"])
def test_the_reaction_equals_gemseo_to_1e12(inputs, expected):
    out = propane.PropaneReaction().compute(_batch(inputs))
    for name, value in expected.items():
        np.testing.assert_allclose(out[name], [value], rtol=1e-12, err_msg=name)


def test_the_optimum_zeroes_every_residual():
    values = {"x_shared": np.array([propane.OPTIMUM])}
    for cls in COMBS:
        values.update(cls().compute(values))
    out = propane.PropaneReaction().compute(values)
    for name in ("f_2", "f_6", "f_7", "f_9", "obj"):
        assert abs(out[name][0]) < 1e-13, name
    np.testing.assert_allclose(propane.OPTIMUM, [1.378887, 18.426810, 1.094798, 0.931214], rtol=1e-6)  # published


def test_an_off_equilibrium_square_root_of_a_negative_fails_the_point():
    """An IDF iterate or a design outside the bounds can make a square root's argument negative: NaN,
    which bev_mdo turns into a failed point (never a silent number)."""
    out = propane.PropaneReaction().compute(_batch({"x_shared": [1.0] * 4, "y_1": [-1.0, 1.0], "y_2": [1.0] * 2,
                                                    "y_3": [1.0] * 3}))
    assert np.isnan(out["f_6"][0]) and np.isnan(out["obj"][0]) and np.isfinite(out["f_2"][0])


def _close_to_optimum(res, obj_tol, x_rel):
    assert res.feasible
    assert abs(res.objective) < obj_tol
    got = [res.design[f"x_shared[{i}]"] for i in range(4)]
    np.testing.assert_allclose(got, propane.OPTIMUM, rtol=x_rel)
    for c in ("f_2", "f_6", "f_7", "f_9"):
        assert res.outputs[c] <= res.feasibility_tolerance


@pytest.mark.parametrize("derivatives", ["analytic", "fd"])
def test_idf_with_slsqp_reaches_the_optimum(derivatives):
    res = _run(_config("idf", **{"optimizer.derivatives": derivatives}))
    assert res.success and res.last_iterate
    _close_to_optimum(res, 1e-8, 1e-7)


def test_mdf_with_slsqp_ends_near_the_optimum():
    """On the development host SLSQP does not converge here (like GEMSEO's); SLSQP's path depends on
    the host's floating-point kernels, so only the nearness is asserted, not the failure."""
    res = _run(_config("mdf"))
    _close_to_optimum(res, 2e-4, 2e-5)


def test_mdf_with_cobyla_reaches_the_optimum():
    res = _run(_config("mdf"), optimizer="COBYLA")
    assert res.success
    _close_to_optimum(res, 1e-8, 1e-7)


@pytest.mark.parametrize("at", ["", "x_shared[0]=1.378887,x_shared[1]=18.42681,x_shared[2]=1.094798,x_shared[3]=0.931214",
                                "x_shared[0]=0.5,x_shared[1]=5,x_shared[2]=1.5,x_shared[3]=0.2"])
def test_check_partials_agrees_with_finite_differences(at):
    from bev_mdo.cli.check_partials import check

    report = check(_config(), at=at)
    assert report["ok"], [m for d in report["disciplines"] for m in d["mismatches"]][:5]
    assert [d["partials"] for d in report["disciplines"]] == ["analytic"] * 4
