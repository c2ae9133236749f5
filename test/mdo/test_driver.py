"""mdo.driver.pick_result: which iteration record a run reports."""
from bev_mdo.mdo.driver import pick_result


def _h(*records):
    return [{"objective": f, "max_violation": v, "feasible": v <= 1e-4} for f, v in records]


def test_a_converged_optimum_is_not_displaced_by_a_point_that_buys_objective_with_violation():
    # SSBJ (maximise range) on one host: SLSQP passed a point 9.2e-5 violated (inside the 1e-4
    # tolerance) with 0.13 nmi more range, then converged to the exact optimum
    h = _h((535.8, 0.2), (3963.5146, 9.2e-5), (3963.3800, 0.0))
    assert pick_result(h, -1.0, converged=True) == 2


def test_an_earlier_point_no_more_violated_and_better_is_the_result():
    # an optimiser that reports success but wandered off to a worse feasible point
    h = _h((10.0, 0.0), (3.18, 1e-9), (7.0, 0.0))
    assert pick_result(h, 1.0, converged=True) == 1


def test_without_convergence_the_best_point_inside_the_tolerance_is_the_result():
    h = _h((10.0, 0.0), (3.18, 5e-5), (7.0, 0.0))
    assert pick_result(h, 1.0, converged=False) == 1
    assert pick_result(h, 1.0, converged=True) == 2


def test_an_infeasible_last_iterate_gives_way_to_the_best_feasible_record():
    h = _h((10.0, 0.0), (8.0, 5e-5), (3.0, 0.3))
    assert pick_result(h, 1.0, converged=True) == 1


def test_a_gain_within_the_relative_tolerance_keeps_the_last_iterate():
    h = _h((5.0, 0.0), (5.0 - 1e-7, 0.0), (5.0, 0.0))
    assert pick_result(h, 1.0, converged=False) == 2


def test_no_feasible_record_gives_the_last():
    h = _h((5.0, 0.1), (4.0, 0.2))
    assert pick_result(h, 1.0, converged=True) == 1
