"""Chebyshev proxies: exactness, adaptivity, one batch per grid, minimum and roots to 1e-8."""
import numpy as np
import pytest
from scipy.optimize import brentq

from bev_mdo.mdo.chebyshev import Cheb2, chebfun1, chebfun2, chebpts2, on_plane, vals2coeffs


def smooth(P):
    x, y = P[:, 0], P[:, 1]
    return (x - 0.3) ** 2 + 2 * (y + 0.1) ** 2 + 0.5 * np.sin(3 * x)


def test_points_and_coefficients_of_x5():
    # Thesis 7.2.1: chebpoly(x^5) = [0.0625 0 0.3125 0 0.625 0] (highest degree first).
    t = chebpts2(5)
    np.testing.assert_allclose(t, np.cos(np.pi * np.arange(6) / 5))
    c = vals2coeffs(t ** 5)
    np.testing.assert_allclose(c[::-1], [0.0625, 0, 0.3125, 0, 0.625, 0], atol=1e-15)


def test_polynomial_is_chopped_to_its_degree():
    p = chebfun1(lambda X: X[:, 0] ** 3 - 2 * X[:, 0], -1.0, 1.0)
    # x^3 - 2x = 0.25 T3 + 0.75 T1 - 2 T1
    np.testing.assert_allclose(p.coef, [0, -1.25, 0, 0.25], atol=1e-14)
    assert p.converged


def test_each_degree_is_one_batch_and_points_are_reused():
    calls = []

    def f(P):
        calls.append(P.shape)
        return smooth(P)
    p = chebfun2(f, (-1, 1), (-1, 1))
    assert p.converged
    # 9x9, then only the new points of 17x17, 33x33: nested grids are reused.
    assert [c[0] for c in calls] == [81, 17 * 17 - 81, 33 * 33 - 17 * 17]
    assert p.n_evaluations == 33 * 33


def test_smooth_function_minimum_to_1e8():
    p = chebfun2(smooth, (-1, 1), (-1, 1))
    x, y, f = p.minimum()
    # Independently: y* = -0.1; x* solves 2(x - 0.3) + 1.5 cos(3x) = 0 (the global one,
    # f''>0 there); the other stationary points of this 1-D function are maxima or higher.
    xs = brentq(lambda x: 2 * (x - 0.3) + 1.5 * np.cos(3 * x), -0.6, 0.0)
    assert abs(x - xs) < 1e-8 and abs(y + 0.1) < 1e-8
    assert abs(f - ((xs - 0.3) ** 2 + 0.5 * np.sin(3 * xs))) < 1e-10


def test_roots_1d_to_1e8():
    p = chebfun1(lambda X: np.cos(3 * X[:, 0]) - X[:, 0], -1.0, 2.0)
    exact = [brentq(lambda x: np.cos(3 * x) - x, a, b) for a, b in ((-1, -0.93), (-0.93, -0.6), (0, 1))]
    np.testing.assert_allclose(p.roots(), exact, atol=1e-8)


def test_zero_contour_of_circle_to_1e8():
    p = chebfun2(lambda P: P[:, 0] ** 2 + P[:, 1] ** 2 - 0.25, (-1, 1), (-1, 1))
    z = p.zero_contour(n_lines=31)
    assert len(z) > 40
    np.testing.assert_allclose(np.hypot(z[:, 0], z[:, 1]), 0.5, atol=1e-8)


def test_constrained_minimum_on_contour():
    # min smooth s.t. x + y >= 0.5, i.e. g = 0.5 - x - y <= 0. The unconstrained minimum
    # (-0.25, -0.1) is infeasible, so the optimum is on x + y = 0.5: with y = 0.5 - x,
    # d/dx: 2(x - 0.3) - 4(0.6 - x) + 1.5 cos(3x) = 0.
    procs = chebfun2(lambda P: {"f": smooth(P), "g": 0.5 - P[:, 0] - P[:, 1]}, (-1, 1), (-1, 1))
    x, y, f = procs["f"].minimum([procs["g"]])
    xs = brentq(lambda x: 2 * (x - 0.3) - 4 * (0.6 - x) + 1.5 * np.cos(3 * x), 0.0, 1.0)
    assert abs(x - xs) < 1e-7 and abs(y - (0.5 - xs)) < 1e-7


def test_infeasible_box_gives_none():
    procs = chebfun2(lambda P: {"f": smooth(P), "g": 5 + P[:, 0]}, (-1, 1), (-1, 1))
    assert procs["f"].minimum([procs["g"]]) is None


def test_on_plane_holds_other_variables():
    seen = []

    def f(X):
        seen.append(X.copy())
        return X.sum(axis=1)
    p = chebfun2(on_plane(f, [10.0, 20.0, 30.0], 0, 2), (0, 1), (0, 1))
    assert np.all(seen[0][:, 1] == 20.0)
    assert abs(p(0.5, 0.5) - 21.0) < 1e-12


@pytest.mark.parametrize("args, match", [
    (((1, 1), (0, 1)), "range of x"),
    (((0, 1), (0, np.inf)), "range of y"),
])
def test_bad_ranges(args, match):
    with pytest.raises(ValueError, match=match):
        chebfun2(smooth, *args)


def test_non_finite_output_is_named():
    with pytest.raises(ValueError, match="'f' is not finite"):
        chebfun1(lambda X: np.where(X[:, 0] < 0, np.nan, X[:, 0]), -1, 1)


def test_unresolved_function_reports_not_converged():
    p = chebfun1(lambda X: np.abs(X[:, 0]), -1, 1, n_max=32)
    assert not p.converged and isinstance(p(0.3), float)
    assert isinstance(chebfun2(smooth, (0, 1), (0, 1)), Cheb2)
