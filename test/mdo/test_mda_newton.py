"""Newton-Raphson MDA (mda.method: newton): same fixed point as Gauss-Seidel, one evaluate() call per
step for the whole loop, analytic partials or a finite-difference Jacobian, per-point failures."""
from pathlib import Path

import numpy as np
import pytest
import yaml
from sellar import SELLAR_OBJECTIVE, SELLAR_OPTIMUM, Failing, SellarDis1, sellar_disciplines
from vector_toys import NoPartials

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo.driver import run_optimization
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA
from bev_mdo.mdo.vectors import wrap

ROOT = Path(__file__).resolve().parents[2]
POINTS = {"z1": np.array([5.0, 1.9776, 3.0, -2.0]), "z2": np.array([2.0, 0.0, 1.0, 7.0]),
          "x": np.array([1.0, 0.0, 4.0, 0.5])}


def _pair(discs_a, discs_b, points, **kw):
    gs = MDA(InProcessEvaluator(discs_a), method="gauss_seidel", tolerance=1e-14, max_iterations=300, **kw).run(points)
    ev = InProcessEvaluator(discs_b)
    mda = MDA(ev, method="newton", tolerance=1e-13, **kw)
    return gs, mda.run(points), mda, ev


def test_sellar_newton_reaches_the_gauss_seidel_fixed_point_in_few_single_call_steps():
    gs, nw, mda, ev = _pair(sellar_disciplines(), sellar_disciplines(), POINTS)
    assert gs.ok.all() and nw.ok.all()
    for v in ("y1", "y2", "obj"):
        np.testing.assert_allclose(nw.values[v], gs.values[v], rtol=1e-10, atol=1e-12)
    assert (nw.iterations <= 6).all() and (nw.iterations < gs.iterations).all()
    # one seeding call (sellar1: y1 is not torn), one call per Newton step, one for the objective
    assert mda.solver.n_calls == nw.iterations.max()
    assert ev.waves == 1 + nw.iterations.max() + 1


def test_newton_without_analytic_partials_uses_a_finite_difference_jacobian_in_the_same_call():
    discs = sellar_disciplines()
    discs[1] = NoPartials(discs[1])
    ev = InProcessEvaluator(discs)
    assert ev.specs["sellar2"].partials is False
    mda = MDA(ev, method="newton", tolerance=1e-13)
    res = mda.run(POINTS)
    gs = MDA(InProcessEvaluator(sellar_disciplines()), tolerance=1e-14, max_iterations=300).run(POINTS)
    assert res.ok.all()
    np.testing.assert_allclose(res.values["y2"], gs.values["y2"], rtol=1e-10)
    assert mda.solver.n_calls == res.iterations.max()  # the stencil travels with the base points
    assert res.iterations.max() <= 8


class _Unknown:
    """An evaluator that, like ROS, does not know beforehand which discipline has partials."""

    def __init__(self, inner):
        import dataclasses

        self.inner, self.counts = inner, inner.counts
        self.specs = {k: dataclasses.replace(s, partials=None) for k, s in inner.specs.items()}
        self.calls = 0

    def evaluate(self, calls, partials=False):
        self.calls += 1
        return self.inner.evaluate(calls, partials)


def test_a_discipline_found_without_partials_is_differenced_from_its_first_answer_on():
    discs = sellar_disciplines()
    discs[1] = NoPartials(discs[1])
    ev = _Unknown(InProcessEvaluator(discs))
    mda = MDA(ev, method="newton", tolerance=1e-13)
    res = mda.run(POINTS)
    assert res.ok.all()
    assert mda.solver.fd_only == {"sellar2"}
    assert mda.solver.n_calls == res.iterations.max() + 1  # one extra stencil call, on the first step
    ref = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", tolerance=1e-13).run(POINTS)
    np.testing.assert_allclose(res.values["y1"], ref.values["y1"], rtol=1e-10)


def test_partials_requested_come_from_the_last_newton_step_at_the_reported_values():
    ev = InProcessEvaluator(sellar_disciplines())
    mda = MDA(ev, method="newton", tolerance=1e-12)
    res = mda.run(POINTS, partials=True)
    waves_plain = InProcessEvaluator(sellar_disciplines())
    MDA(waves_plain, method="newton", tolerance=1e-12).run(POINTS)
    assert ev.waves == waves_plain.waves  # no extra call for the partials
    y1 = res.values["y1"]
    np.testing.assert_allclose(res.partials["sellar2"][("y2", "y1")], 0.5 / np.sqrt(y1), rtol=1e-15)
    np.testing.assert_allclose(res.partials["sellar1"][("y1", "z1")], 2 * POINTS["z1"], rtol=1e-15)
    np.testing.assert_allclose(res.partials["sellar_obj"][("obj", "y2")], -np.exp(-res.values["y2"]), rtol=1e-15)


def test_unconverged_and_failed_points_are_per_point_like_the_other_methods():
    res = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", max_iterations=2).run(POINTS)
    assert not res.ok.any()
    assert np.isnan(res.values["obj"]).all()
    assert "did not converge in 2 newton iterations" in res.messages[0]
    assert {(e.kind, e.discipline, e.loop) for e in res.errors} == {("not_converged", "", ("sellar1", "sellar2"))}
    assert [e.point for e in res.errors] == [0, 1, 2, 3]
    discs = sellar_disciplines()
    discs[0] = Failing(SellarDis1(), "x", 3.0)
    res = MDA(InProcessEvaluator(discs), method="newton").run(POINTS)
    assert res.ok.tolist() == [True, True, False, True]
    assert "sellar1" in res.messages[2] and np.isnan(res.values["y1"][2])
    assert (res.errors[2].kind, res.errors[2].discipline, res.errors[2].point) == ("discipline", "sellar1", 2)
    assert res.errors[0] is res.errors[1] is res.errors[3] is None
    gs = MDA(InProcessEvaluator(sellar_disciplines()), tolerance=1e-14, max_iterations=300).run(POINTS)
    np.testing.assert_allclose(res.values["y1"][[0, 1, 3]], gs.values["y1"][[0, 1, 3]], rtol=1e-9)


class _Flat:
    """y = x y + 1: the Newton matrix 1 - x is singular at x = 1 (no fixed point there); y = 1 / (1 - x) else."""

    name, inputs, outputs = "flat", ("x", "y"), ("y",)

    def compute(self, inputs):
        return {"y": inputs["x"] * inputs["y"] + 1.0}

    def compute_partials(self, inputs):
        return {("y", "y"): inputs["x"], ("y", "x"): inputs["y"]}


def test_a_singular_newton_system_fails_that_point_only():
    res = MDA(InProcessEvaluator([_Flat()]), method="newton", guesses={"y": 0.0}).run({"x": np.array([0.5, 1.0])})
    assert res.ok.tolist() == [True, False]
    assert "singular Newton system" in res.messages[1]
    assert res.errors[1].kind == "singular" and res.errors[1].loop == ("flat",) and res.errors[1].point == 1
    assert res.values["y"][0] == pytest.approx(2.0, rel=1e-12)


# ------------------------------------------------------------------ vector couplings
class _VecA:
    name, inputs, outputs = "vec_a", ("x", "b"), ("a",)
    shapes = {"a": 3, "b": 2}

    def compute(self, inputs):
        b, x = inputs["b"], inputs["x"]
        return {"a": np.stack([x + 0.3 * np.tanh(b[:, 0]), 2 * x - 0.2 * b[:, 1], 0.1 * b[:, 0] * b[:, 1]], axis=1)}

    def compute_partials(self, inputs):
        b, x = inputs["b"], inputs["x"]
        n = len(x)
        dab = np.zeros((n, 3, 2))
        dab[:, 0, 0] = 0.3 / np.cosh(b[:, 0]) ** 2
        dab[:, 1, 1] = -0.2
        dab[:, 2, 0], dab[:, 2, 1] = 0.1 * b[:, 1], 0.1 * b[:, 0]
        return {("a", "b"): dab, ("a", "x"): np.stack([np.ones(n), 2 * np.ones(n), np.zeros(n)], axis=1)[:, :, None]}


class _VecB:
    name, inputs, outputs = "vec_b", ("a",), ("b",)
    shapes = {"a": 3, "b": 2}

    def compute(self, inputs):
        a = inputs["a"]
        return {"b": np.stack([0.5 * np.sin(a[:, 0]) + a[:, 2], 0.4 * a[:, 1] + 1.0], axis=1)}

    def compute_partials(self, inputs):
        a = inputs["a"]
        d = np.zeros((len(a), 2, 3))
        d[:, 0, 0], d[:, 0, 2], d[:, 1, 1] = 0.5 * np.cos(a[:, 0]), 1.0, 0.4
        return {("b", "a"): d}


def test_vector_couplings_newton_equals_gauss_seidel():
    x = {"x": np.array([0.1, 0.7, 1.3])}
    gs, nw, mda, _ = _pair([wrap(_VecA()), wrap(_VecB())], [wrap(_VecA()), wrap(_VecB())], x)
    assert gs.ok.all() and nw.ok.all()
    assert len(mda.graph.cycles[0]) == 2
    for v in ("a[0]", "a[1]", "a[2]", "b[0]", "b[1]"):
        np.testing.assert_allclose(nw.values[v], gs.values[v], rtol=1e-10, atol=1e-12)
    assert (nw.iterations <= 6).all() and (nw.iterations < gs.iterations).all()


def _sellar_vector(method):
    raw = yaml.safe_load((ROOT / "examples" / "sellar_vector.yaml").read_text())
    raw["mda"]["method"] = method
    return load_config(raw)


def test_vector_sellar_example_newton_equals_gauss_seidel():
    pts = {"z[0]": np.array([5.0, 1.98, -1.0]), "z[1]": np.array([2.0, 0.0, 3.0]), "x": np.array([1.0, 0.0, 2.0])}
    out = {}
    for m in ("gauss_seidel", "newton"):
        cfg = _sellar_vector(m)
        tol = 1e-13 if m == "newton" else 1e-14
        out[m] = MDA(InProcessEvaluator(resolve_disciplines(cfg)), method=m, tolerance=tol, max_iterations=300).run(pts)
        assert out[m].ok.all()
    for v in ("y1", "y2", "obj", "con[0]", "con[1]"):
        np.testing.assert_allclose(out["newton"].values[v], out["gauss_seidel"].values[v], rtol=1e-10, atol=1e-12)


def test_battery_sized_bev_loop_newton_equals_gauss_seidel():
    """vehicle_mass -> energy -> battery_sizing -> vehicle_mass; energy has no partials (FD columns)."""
    from test_bev import sized_config

    pts = {"motor_kw": np.array([80.0, 60.0, 110.0]), "gear_ratio": np.array([8.0, 7.0, 9.5])}
    res = {}
    for m, tol in (("gauss_seidel", 1e-14), ("newton", 1e-13)):
        cfg = sized_config(m)
        ev = InProcessEvaluator(resolve_disciplines(cfg))
        mda = MDA(ev, method=m, tolerance=tol, max_iterations=300,
                  guesses=cfg["problem"].get("coupling_guesses") or {"battery_kwh": 40.0})
        inputs = {**pts, **{k: np.full(3, v) for k, v in cfg["problem"].get("parameters", {}).items()}}
        res[m] = mda.run(inputs)
        assert res[m].ok.all(), res[m].errors
    assert "energy" in mda.solver.fd_only
    assert "battery_kwh" in res["newton"].values
    for v in res["gauss_seidel"].values:
        np.testing.assert_allclose(res["newton"].values[v], res["gauss_seidel"].values[v], rtol=1e-10, err_msg=v)
    assert (res["newton"].iterations < res["gauss_seidel"].iterations).all()


@pytest.mark.parametrize("config", ["sellar_mdf_newton.yaml", "sellar_mdf.yaml"])
def test_sellar_mdf_reaches_the_reference_with_either_mda(config):
    cfg = load_config(ROOT / "examples" / "sellar" / config)
    r = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
    assert r.feasible
    assert r.objective == pytest.approx(SELLAR_OBJECTIVE, abs=1e-8)
    assert r.design["z1"] == pytest.approx(SELLAR_OPTIMUM["z1"], abs=1e-6)


def test_config_accepts_newton_and_rejects_unknown_methods(tmp_path):
    cfg = load_config(ROOT / "examples" / "sellar" / "sellar_mdf_newton.yaml")
    assert cfg["mda"]["method"] == "newton"
    raw = yaml.safe_load((ROOT / "examples" / "sellar" / "sellar_mdf_newton.yaml").read_text())
    raw["mda"]["method"] = "newtn"
    with pytest.raises(ValueError, match="mda.method 'newtn' is unknown; allowed: gauss_seidel, jacobi, newton"):
        load_config(raw)


# ------------------------------------------------------------------ MDF gradients through a Newton MDA
def _with(path, method, derivatives, **problem):
    raw = yaml.safe_load(Path(path).read_text())
    raw["mda"]["method"] = method
    raw.setdefault("optimizer", {})["derivatives"] = derivatives
    raw["problem"].update(problem)
    return load_config(raw)


@pytest.mark.parametrize("path, sized", [(ROOT / "examples" / "sellar_vector.yaml", False),
                                         (ROOT / "config" / "leaf_nedc.yaml", True)])
def test_assembled_mdf_gradients_through_newton_equal_those_through_gauss_seidel(path, sized):
    """Newton's last-step partials (Sellar: all analytic; the sized BEV loop: energy differenced
    alone at the converged values) give the Gauss-Seidel run's assembled gradient, and central
    differences of the whole MDF."""
    from bev_mdo.mdo.driver import build_formulation

    extra = {"battery_sized_for_range": True} if sized else {}
    grads = {}
    for method in ("gauss_seidel", "newton"):
        cfg = _with(path, method, "analytic", **extra)
        cfg["mda"]["tolerance"] = 1e-13
        form = build_formulation(cfg, InProcessEvaluator(resolve_disciplines(cfg)), "mdf")
        u = form.to_u(form.x0)
        df, dg, _ = form.gradients(u)
        grads[method] = np.vstack([df[None], dg])
    np.testing.assert_allclose(grads["newton"], grads["gauss_seidel"], rtol=1e-6, atol=1e-9)
    cfg = _with(path, "newton", "fd", **extra)
    cfg["mda"]["tolerance"] = 1e-13
    form = build_formulation(cfg, InProcessEvaluator(resolve_disciplines(cfg)), "mdf")
    h, cols = 1e-6, []
    for j in range(len(u)):
        e = np.zeros(len(u))
        e[j] = h
        fp, gp, _ = form.evaluate_batch(form.to_x(u + e)[None])
        fm, gm, _ = form.evaluate_batch(form.to_x(u - e)[None])
        cols.append(np.concatenate([fp - fm, gp[0] - gm[0]]) / (2 * h))
    ref = np.array(cols).T
    np.testing.assert_allclose(grads["newton"], ref, rtol=2e-5, atol=2e-6 * max(1.0, np.abs(ref).max()))


def test_the_sellar_example_partials_pass_check_partials():
    import subprocess
    import sys

    p = subprocess.run([sys.executable, "-m", "bev_mdo", "check-partials", str(ROOT / "examples" / "sellar" /
                        "sellar_mdf_newton.yaml"), "--at", "z1=2,z2=1,x=0.5"], capture_output=True, text=True,
                       timeout=120, cwd=ROOT)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "all analytic partials agree" in p.stdout
    assert all(f"{d} " in p.stdout for d in ("sellar1", "sellar2", "sellar_obj"))


def test_relaxation_damps_the_newton_step_not_the_solution():
    plain = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", tolerance=1e-13).run(POINTS)
    damped = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", tolerance=1e-13,
                 relaxation=0.5).run(POINTS)
    assert damped.ok.all()
    assert (damped.iterations > plain.iterations).all()
    np.testing.assert_allclose(damped.values["y1"], plain.values["y1"], rtol=1e-11)
