"""chebyshev-pairwise: analytic optimum, infeasible start, default BEV problem vs SLSQP, bad input."""
from pathlib import Path

import numpy as np
import pytest

from bev_mdo.mdo.chebyshev_opt import minimize

ROOT = Path(__file__).resolve().parents[2]


def product_problem(X):
    # min x0 + x1 + x2 s.t. x0 x1 x2 >= 8: by AM-GM the optimum is (2, 2, 2), f = 6.
    return X.sum(axis=1), (1.0 - X.prod(axis=1) / 8.0)[:, None]


def vertex_problem(X):
    # min -(x0 + 2 x1) + x2^2 s.t. x0 + x1 <= 3, x1 <= 2 (normalised), x in [0, 4]^2 x [-1, 1]:
    # LP vertex x0 = 1, x1 = 2 and x2 = 0 -> f = -5.
    f = -(X[:, 0] + 2 * X[:, 1]) + X[:, 2] ** 2
    return f, np.stack([(X[:, 0] + X[:, 1] - 3) / 3, (X[:, 1] - 2) / 2], axis=1)


def test_analytic_curved_constraint_optimum():
    seen = []
    r = minimize(product_problem, [4, 4, 4], [0.5] * 3, [5] * 3, {}, seen.append)
    assert r.success
    assert abs(r.fun - 6.0) < 1e-9
    np.testing.assert_allclose(r.x, [2, 2, 2], rtol=1e-4)
    assert len(seen) == r.nit > 0
    assert r.nbatch < r.nfev  # points travel in batches


def test_infeasible_start_is_restored():
    r = minimize(product_problem, [1, 1, 1], [0.5] * 3, [5] * 3, {}, None)
    assert r.success and abs(r.fun - 6.0) < 1e-9


def test_vertex_optimum():
    r = minimize(vertex_problem, [0.5, 0.5, 0.7], [0, 0, -1], [4, 4, 1], {}, None)
    assert r.success
    np.testing.assert_allclose(r.x, [1, 2, 0], atol=1e-6)
    assert abs(r.fun + 5) < 1e-8


@pytest.mark.parametrize("args, match", [
    (([1.0], [0.0], [2.0], {}), "at least 2 design variables"),
    (([1.0, 1.0], [0.0, 0.0], [2.0, np.inf], {}), "finite bounds"),
    (([1.0, 1.0], [0.0, 0.0], [2.0, 2.0], {"boxx": 1}), "unknown chebyshev-pairwise option 'boxx'"),
])
def test_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        minimize(product_problem, *args, None)


def test_default_bev_problem_reaches_slsqp_optimum():
    cfg_path = ROOT / "config" / "leaf_nedc.yaml"
    from bev_mdo import config as config_mod
    from bev_mdo.mdo import driver
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    cfg = config_mod.load_config(cfg_path)

    def run(opt):
        ev = InProcessEvaluator(config_mod.resolve_disciplines(cfg))
        return driver.run_optimization(cfg, ev, optimizer=opt)
    ref, cheb = run("SLSQP"), run("chebyshev-pairwise")
    assert ref.feasible and cheb.feasible
    assert abs(cheb.objective - ref.objective) <= 1e-3 * abs(ref.objective)
    for k, v in ref.design.items():
        assert abs(cheb.design[k] - v) <= 1e-3 * abs(v), k


def test_no_feasible_start_names_the_constraint_by_how_much_and_what_to_do():
    """SSBJ with chebyshev-pairwise ended 'could not find a feasible start point' (exit 2) and nothing else.
    Here Sellar's y1 >= 500 cannot hold (y1 stays below 130 in the box)."""
    from bev_mdo.config import resolve_disciplines
    from bev_mdo.mdo import driver
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from bev_mdo.testing import example_config

    config = example_config(ROOT / "examples/sellar/sellar_mdf.yaml", **{"problem.constraints.y1.lower": 500.0})
    with pytest.raises(ValueError) as err:
        driver.run_optimization(config, InProcessEvaluator(resolve_disciplines(config)),
                                optimizer="chebyshev-pairwise")
    line = str(err.value)
    assert line.startswith("chebyshev-pairwise: could not find a feasible start point: y1 >= 500 violated by ")
    by = float(line.split("violated by ")[1].split(";")[0])
    assert 370 < by <= 500  # y1 <= 130 in the box
    assert line.endswith("(--initial NAME=X) or use another optimizer (SLSQP, COBYLA)") and "\n" not in line


def test_the_iteration_limit_is_not_convergence():
    """chebyshev-pairwise stopped by maxiter reported success (it was feasible), so a run cut short was said
    to have converged ('chebyshev-pairwise says it converged, but the first-order conditions do not hold')
    and the reason it stopped was never printed."""
    cut = minimize(product_problem, [4, 4, 4], [0.5] * 3, [5] * 3, {"maxiter": 1})
    assert not cut.success and cut.message == "maximum number of iterations reached" and cut.nit == 1
    done = minimize(product_problem, [4, 4, 4], [0.5] * 3, [5] * 3, {})
    assert done.success and done.message == "trust box below xtol"
