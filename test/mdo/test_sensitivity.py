"""Normalised sensitivities: thesis toy examples (eqs 5-6..5-11), symmetry, labels, errors."""
import numpy as np
import pytest

from bev_mdo.mdo.sensitivity import coupling_label, sensitivities


def toy_linear(X):  # eq 5-6: E = 0.5 p1 + 0.5 p2
    return {"E": 0.5 * X[:, 0] + 0.5 * X[:, 1]}


def toy_ratio(X):  # eq 5-9: E = p1 / p2
    return {"E": X[:, 0] / X[:, 1]}


def test_eq_5_6_linear_toy():
    s = sensitivities(toy_linear, {"p1": 1.0, "p2": 1.0}, order=2)
    # By hand: dE/dp_i = 0.5, E = 1 -> S = [0.5, 0.5] (eq 5-7); all d2E = 0 (eq 5-8).
    np.testing.assert_allclose(s.first["E"], [0.5, 0.5], atol=1e-12)
    np.testing.assert_allclose(s.second["E"], np.zeros((2, 2)), atol=1e-10)


def test_eq_5_9_ratio_toy():
    s = sensitivities(toy_ratio, {"p1": 1.0, "p2": 1.0}, order=2)
    # By hand at (1, 1), E = 1: dE/dp1 = 1/p2 = 1, dE/dp2 = -p1/p2^2 = -1 (eq 5-10);
    # d2E/dp1^2 = 0, d2E/dp1dp2 = -1/p2^2 = -1, d2E/dp2^2 = 2 p1/p2^3 = 2 (eq 5-11).
    np.testing.assert_allclose(s.first["E"], [1.0, -1.0], atol=1e-9)
    np.testing.assert_allclose(s.second["E"], [[0.0, -1.0], [-1.0, 2.0]], atol=1e-8)
    assert s.n_batches == 1


def test_ratio_toy_off_nominal_normalisation():
    # At (2, 4): E = 0.5; S1 = (1/4)*2/0.5 = 1, S2 = (-2/16)*4/0.5 = -1;
    # S'12 = (-1/16)*8/0.5 = -1, S'22 = (2*2/64)*16/0.5 = 2: normalisation is scale free.
    s = sensitivities(toy_ratio, {"p1": 2.0, "p2": 4.0}, order=2)
    np.testing.assert_allclose(s.first["E"], [1.0, -1.0], atol=1e-8)
    np.testing.assert_allclose(s.second["E"], [[0.0, -1.0], [-1.0, 2.0]], atol=1e-7)


def test_complex_step_is_exact_for_ratio():
    s = sensitivities(toy_ratio, {"p1": 1.0, "p2": 3.0}, method="complex")
    assert s.method == "complex"
    np.testing.assert_allclose(s.gradient["E"], [1 / 3, -1 / 9], rtol=1e-15)


def test_auto_falls_back_to_central_when_model_is_real_only():
    def real_only(X):
        X = np.asarray(X, dtype=float)
        return {"E": X[:, 0] / X[:, 1]}
    s = sensitivities(real_only, {"p1": 1.0, "p2": 3.0}, method="auto")
    assert s.method == "central"
    np.testing.assert_allclose(s.gradient["E"], [1 / 3, -1 / 9], rtol=1e-8)
    with pytest.raises(ValueError, match="complex step"):
        sensitivities(real_only, {"p1": 1.0, "p2": 3.0}, method="complex")


def test_second_order_symmetric_and_matches_analytic_hessian():
    def f(X):
        x, y, z = X.T
        return {"f": np.exp(0.3 * x) * y ** 2 + np.sin(x * z) + 5.0}
    p = {"x": 0.7, "y": 1.3, "z": 2.1}
    s = sensitivities(f, p, order=2)
    H = s.hessian["f"]
    np.testing.assert_array_equal(H, H.T)
    x, y, z = 0.7, 1.3, 2.1
    e = np.exp(0.3 * x)
    exact = np.array([
        [0.09 * e * y ** 2 - z ** 2 * np.sin(x * z), 0.6 * e * y, np.cos(x * z) - x * z * np.sin(x * z)],
        [0.6 * e * y, 2 * e, 0.0],
        [np.cos(x * z) - x * z * np.sin(x * z), 0.0, -x ** 2 * np.sin(x * z)],
    ])
    np.testing.assert_allclose(H, exact, atol=1e-7)
    # The Richardson error estimate is an honest (not tiny, not absurd) bound here.
    assert np.all(np.abs(H - exact) <= 10 * s.second_error["f"] / np.outer([x, y, z], [x, y, z]) * s.values["f"] + 1e-9)


def test_stencil_is_one_batch_and_steps_reported():
    calls = []

    def f(X):
        calls.append(X.shape)
        return {"f": X[:, 0] * X[:, 1] * X[:, 2] + 1}
    s = sensitivities(f, {"a": 1.0, "b": 2.0, "c": 3.0}, order=2, rel_step=1e-3)
    assert len(calls) == 1 and calls[0][0] == s.n_evaluations
    np.testing.assert_allclose(s.step, [1e-3, 2e-3, 3e-3])
    # f = abc + 1 = 7: S'_ab = 1*ab/7 = c*a*b/7 = 6/7 for each pair, 0 on the diagonal.
    np.testing.assert_allclose(s.second["f"], 6 / 7 * (1 - np.eye(3)), atol=1e-9)


def test_wrt_subset_holds_other_variables():
    s = sensitivities(toy_ratio, {"p1": 2.0, "p2": 4.0}, wrt=["p2"], order=2)
    assert s.names == ("p2",)
    np.testing.assert_allclose(s.second["E"], [[2.0]], atol=1e-7)


def test_point_on_bound_uses_one_sided_stencil():
    s = sensitivities(toy_ratio, {"p1": 1.0, "p2": 1.0}, order=2, bounds={"p2": (1.0, 2.0), "p1": (0, 1)})
    assert set(s.one_sided) == {"p1", "p2"}
    np.testing.assert_allclose(s.second["E"], [[0.0, -1.0], [-1.0, 2.0]], atol=1e-5)
    np.testing.assert_allclose(s.first["E"], [1.0, -1.0], atol=1e-7)


def test_thesis_fig_5_3_values_get_thesis_labels():
    # Fig 5-3(a) NEDC upper triangle (values, labels) as printed in the thesis.
    pairs = [(0.0, "NC"), (-0.36, "MC"), (-0.28, "MC"), (0.28, "MC"), (-0.27, "MC"),
             (-0.21, "MC"), (-0.88, "VSC"), (-0.69, "SC"), (-0.13, "MC"), (0.91, "VSC"),
             (-0.18, "MC"), (-0.14, "MC"), (0.94, "VSC"), (-0.87, "VSC"), (0.20, "MC")]
    for value, label in pairs:
        assert coupling_label(value) == label, value


@pytest.mark.parametrize("kwargs, match", [
    (dict(wrt=["p3"]), "unknown variable 'p3'"),
    (dict(bounds={"p1": (2.0, 3.0)}), "outside its bounds"),
    (dict(bounds={"nope": (0.0, 1.0)}), "unknown bounded variable"),
    (dict(order=3), "order must be 1 or 2"),
])
def test_bad_input_is_one_line_value_error(kwargs, match):
    with pytest.raises(ValueError, match=match) as exc:
        sensitivities(toy_ratio, {"p1": 1.0, "p2": 1.0}, **kwargs)
    assert "\n" not in str(exc.value)


def test_an_output_that_is_zero_keeps_its_derivatives():
    """S = (x/f) df/dx is undefined where f = 0; the derivatives are not, and the objective's zero
    stopped the whole analysis (every other output's sensitivities with it)."""
    def f(X):
        return {"E": X[:, 0] ** 2 - 1.0, "other": 3.0 * X[:, 0]}
    for order in (1, 2):
        s = sensitivities(f, {"p1": 1.0}, order=order)
        assert s.values["E"] == 0 and np.isnan(s.first["E"]).all()
        assert s.gradient["E"] == pytest.approx([2.0], rel=1e-6)
        assert s.first["other"] == pytest.approx([1.0], rel=1e-9)
    assert s.hessian["E"][0, 0] == pytest.approx(2.0, rel=1e-4) and s.labels("E").tolist() == [[""]]


# --- CLI: bev-mdo sensitivity (needs the engine, built-in disciplines and config) ---------
from pathlib import Path  # noqa: E402

CONFIG = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"


def _cli(argv):
    from bev_mdo.cli import main
    return main(["sensitivity", str(CONFIG), "--transport", "inprocess", *argv])


def test_cli_json_png_and_range_identity(tmp_path, capsys):
    import json
    png = tmp_path / "h.png"
    rc = _cli(["--at", "motor_kw=80,gear_ratio=8,battery_kwh=24", "--order", "2", "--json", "--png", str(png)])
    assert rc == 0 and png.read_bytes()[:4] == b"\x89PNG"
    d = json.loads(capsys.readouterr().out)
    e = np.array(d["first_order"]["energy_wh_per_km"]["normalised"])
    r = np.array(d["first_order"]["range_km"]["normalised"])
    # range = battery * 1000 / E (eq 7-28) -> S_range = [0, 0, 1] - S_E exactly.
    np.testing.assert_allclose(r, np.array([0, 0, 1.0]) - e, atol=1e-6)
    assert d["n_batches"] == 1
    # motor speed = i_g v_max / r_w (eq 7-24): S = [0, 1, 0], no coupling.
    np.testing.assert_allclose(d["first_order"]["motor_speed_max_rad_s"]["normalised"], [0, 1, 0], atol=1e-8)


def test_a_point_outside_the_bounds_is_taken_as_given_and_said(capsys):
    """A Kona trial: sensitivity --at refused a design outside the bounds (exit 2) that evaluate, check-totals and
    check-partials take as given with a note. The stencil is then central about it (the bounds are not its room)."""
    import json

    assert _cli(["--at", "motor_kw=200", "--json"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ("bev-mdo sensitivity: note: motor_kw = 200 is outside its bounds [40, 120] "
                            "(evaluated as given)\n")
    d = json.loads(captured.out)
    assert d["point"]["motor_kw"] == 200 and "motor_kw" not in d["one_sided"]
    # a review: beyond what the models take it failed at all 37 points (exit 1); at their limit, at 36 of them
    assert _cli(["--at", "motor_kw=-5"]) == 2
    assert capsys.readouterr().err.strip() == ("bev-mdo sensitivity: error: motor_kw: -5 is outside [1, 1000] kW, where "
                                               "discipline 'vehicle_mass' accepts it; such a design cannot be evaluated")
    assert _cli(["--at", "motor_kw=1000", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["one_sided"] == ["motor_kw"]  # the models' limit bounds its steps


@pytest.mark.parametrize("argv, match", [
    (["--wrt", "foo"], "unknown variable or parameter 'foo'"),
    (["--at", "motor_kw"], "must be NAME=VALUE"),
])
def test_cli_bad_input_exit_2(argv, match, capsys):
    assert _cli(argv) == 2
    err = capsys.readouterr().err.strip()
    assert match in err and "\n" not in err


def test_an_output_zero_but_for_rounding_has_no_normalised_sensitivity():
    """A derivatives trial: v = 0.4 u + x1 x2 - ... left 1.15e-14 of a cancellation, and the table printed
    S = -448536643050042.75, unmarked. Here x y - 0.3 at (3, 0.1) is 5.6e-17 in floating point."""
    def f(X):
        return {"zero": X[:, 0] * X[:, 1] - 0.3, "product": X[:, 0] * X[:, 1]}

    s = sensitivities(f, {"x": 3.0, "y": 0.1}, order=2)
    assert 0 < abs(s.values["zero"]) < 1e-15 and s.undefined == ["zero"]
    assert np.isnan(s.first["zero"]).all() and np.isnan(s.second["zero"]).all()
    np.testing.assert_allclose(s.gradient["zero"], [0.1, 3.0], rtol=1e-6)  # the derivatives stay
    np.testing.assert_allclose(s.first["product"], [1.0, 1.0], rtol=1e-6)
    small = sensitivities(lambda X: {"g": X[:, 0] * 1e-12}, {"x": 2.0})  # small but no residue: S = 1
    assert small.undefined == [] and small.first["g"][0] == pytest.approx(1.0)
    # a review: a margin of 0.001 of terms of 1e6 is no rounding (1e6 eps is 2e-10): its S_q = 1 stays
    margin = sensitivities(lambda X: {"m": 1e6 * (X[:, 0] - 1.0) + 1e-3 * X[:, 1]}, {"p": 1.0, "q": 1.0})
    assert margin.undefined == [] and margin.first["m"][1] == pytest.approx(1.0, rel=1e-3)
    # rounding in terms larger than x df/dx: SSBJ's active g_2 at its optimum was -2.1e-14 where x df/dx is 0.24,
    # and printed S = -1.1e13 (9e-14 of it); here 1e-13 of terms of 1e3 times x df/dx
    big = sensitivities(lambda X: {"g": (1e3 + X[:, 0]) - (1e3 + 0.25) + 2e-14 * X[:, 1]}, {"x": 0.25, "y": 1.0})
    assert big.undefined == ["g"] and np.isnan(big.first["g"]).all()
