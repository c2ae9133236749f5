"""Newton MDA with a warm start (mda.warm_start) and with the downstream disciplines fused into the
Newton steps' request waves (mda.fuse_downstream): the cold MDA's results to the tolerance, fewer
request waves, deterministic (the same sequence of MDAs gives the same values bit for bit)."""
import numpy as np
import pytest
import yaml
from sellar import Failing, SellarObjective, sellar_disciplines

from bev_mdo.config import load_config
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA

# an SLSQP-like trajectory: a far start, big steps, then steps of 1e-2 .. 1e-9 near the optimum
TRAJECTORY = [(5.0, 2.0, 1.0), (2.931461, 0.0, 0.0), (2.143681, 0.0, 0.002802), (1.984734, 0.0, 0.0),
              (1.977653, 0.0, 0.0), (1.97763888, 0.0, 0.0), (1.977638881, 0.0, 0.0), (1.977638881, 0.0, 0.0)]
TOL = 1e-12


def _point(z1, z2, x):
    return {"z1": np.array([z1]), "z2": np.array([z2]), "x": np.array([x])}


def _sequence(points, **kw):
    ev = InProcessEvaluator(sellar_disciplines())
    mda = MDA(ev, method="newton", tolerance=TOL, **kw)
    out = []
    for p in points:
        w0 = ev.waves
        out.append((mda.run(p, partials=True), ev.waves - w0))
    return out, mda


def test_warm_start_is_the_default_for_newton_only_and_can_be_switched():
    ev = InProcessEvaluator(sellar_disciplines())
    assert MDA(ev, method="newton").warm_start
    assert not MDA(ev, method="gauss_seidel").warm_start and not MDA(ev, method="jacobi").warm_start
    assert not MDA(ev, method="newton", warm_start=False).warm_start
    assert MDA(ev, method="gauss_seidel", warm_start=True).warm_start
    assert not MDA(ev, method="gauss_seidel", fuse_downstream=True).fuse_downstream  # newton only
    with pytest.raises(ValueError, match="warm_start"):
        MDA(ev, method="newton", warm_start="yes")
    with pytest.raises(ValueError, match="fuse_downstream"):
        MDA(ev, method="newton", fuse_downstream=1)


@pytest.mark.parametrize("fuse", [False, True])
def test_warm_started_mdas_equal_cold_ones_to_the_tolerance_with_fewer_waves(fuse):
    pts = [_point(*p) for p in TRAJECTORY]
    cold, _ = _sequence(pts, warm_start=False)
    warm, mda = _sequence(pts, fuse_downstream=fuse)
    for (c, wc), (w, ww) in zip(cold, warm):
        assert c.ok.all() and w.ok.all()
        for v in ("y1", "y2", "obj"):
            np.testing.assert_allclose(w.values[v], c.values[v], rtol=10 * TOL, atol=10 * TOL)
        for d in ("sellar1", "sellar2", "sellar_obj"):
            for k, col in c.partials[d].items():
                np.testing.assert_allclose(w.partials[d][k], col, rtol=1e-10, atol=1e-12)
        assert ww <= wc
    assert sum(ww for _, ww in warm) < sum(wc for _, wc in cold)
    # cold: 1 seeding call + Newton steps + 1 objective call; warm: no seeding call after the first MDA
    for (c, wc), (w, ww) in zip(cold, warm):
        assert wc == 1 + c.iterations[0] + 1
    assert warm[0][1] == 1 + warm[0][0].iterations[0] + (0 if fuse else 1)  # the first MDA is cold
    for w, ww in warm[1:]:
        assert ww == w.iterations[0] + (0 if fuse else 1)
    # the same design twice: the warm start is the fixed point, one Newton step verifies it
    assert warm[-1][0].iterations[0] <= 2
    assert mda.solver.warm[("sellar1", "sellar2")]["y1"] == warm[-1][0].values["y1"][0]


def test_warm_start_is_deterministic_and_history_dependent_only_below_the_tolerance():
    pts = [_point(*p) for p in TRAJECTORY]
    a, _ = _sequence(pts)
    b, _ = _sequence(pts)
    for (ra, _), (rb, _) in zip(a, b):  # the same sequence: the same values, bit for bit
        assert ra.values["obj"][0] == rb.values["obj"][0] and ra.values["y1"][0] == rb.values["y1"][0]
    rev, _ = _sequence(pts[::-1])  # another history: equal to the tolerance
    for (ra, _), (rr, _) in zip(a, rev[::-1]):
        np.testing.assert_allclose(rr.values["y2"], ra.values["y2"], rtol=10 * TOL)


def test_a_batch_starts_every_point_from_the_first_converged_point_of_the_last_mda():
    batch = {"z1": np.array([5.0, 1.9776, 3.0, -2.0]), "z2": np.array([2.0, 0.0, 1.0, 7.0]),
             "x": np.array([1.0, 0.0, 4.0, 0.5])}
    discs = sellar_disciplines()
    discs[0] = Failing(discs[0], "x", 0.75)  # point 0 fails: the first converged point is point 1
    ev = InProcessEvaluator(discs)
    mda = MDA(ev, method="newton", tolerance=TOL)
    first = mda.run(batch)
    assert first.ok.tolist() == [False, True, False, True]
    assert mda.solver.warm[("sellar1", "sellar2")] == {"y1": first.values["y1"][1], "y2": first.values["y2"][1]}
    cold = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", tolerance=TOL, warm_start=False)
    shifted = {k: v + 1e-3 * (k != "z2") for k, v in batch.items()}
    ref = cold.run(shifted)
    again = mda.run(shifted)
    assert again.ok.tolist() == [False, True, False, True]  # point 2 fails again (x > 0.75)
    np.testing.assert_allclose(again.values["y1"][[1, 3]], ref.values["y1"][[1, 3]], rtol=10 * TOL)
    assert again.iterations[1] < ref.iterations[1]  # the point next to the warm start


def test_a_given_coupling_column_still_overrides_the_warm_start():
    ev = InProcessEvaluator(sellar_disciplines())
    mda = MDA(ev, method="newton", tolerance=TOL, max_iterations=1)
    ok = MDA(ev, method="newton", tolerance=TOL)
    ok.run(_point(1.9776, 0.0, 0.0))
    mda.solver.warm = dict(ok.solver.warm)
    res = mda.run({**_point(1.9776, 0.0, 0.0), "y1": np.array([50.0]), "y2": np.array([50.0])})
    assert not res.ok[0]  # started from the given (far) couplings, not from the warm start


def test_gauss_seidel_warm_start_when_asked_equals_cold_to_the_tolerance_in_fewer_sweeps():
    pts = [_point(*p) for p in TRAJECTORY]
    ev_c, ev_w = InProcessEvaluator(sellar_disciplines()), InProcessEvaluator(sellar_disciplines())
    cold = MDA(ev_c, tolerance=1e-12, max_iterations=300)
    warm = MDA(ev_w, tolerance=1e-12, max_iterations=300, warm_start=True)
    for p in pts:
        c, w = cold.run(p), warm.run(p)
        np.testing.assert_allclose(w.values["obj"], c.values["obj"], rtol=1e-10)
    assert ev_w.waves < ev_c.waves


# ------------------------------------------------------------------ fused downstream disciplines
class _Tail2:
    """Reads the objective (the output of a fused discipline): one wave later, never fused."""

    name, inputs, outputs = "tail2", ("obj",), ("obj2",)

    def compute(self, inputs):
        return {"obj2": 2 * inputs["obj"]}


class _ReadsLoopOnlyOutput:
    """Reads y3, a loop output that no loop discipline reads (its step value is one step late)."""

    name, inputs, outputs = "reads_y3", ("y3",), ("w",)

    def compute(self, inputs):
        return {"w": inputs["y3"] + 1}


class _Dis2WithY3:
    name, inputs, outputs = "sellar2", ("z1", "z2", "y1"), ("y2", "y3")

    def __init__(self):
        from sellar import SellarDis2
        self.inner = SellarDis2()

    def compute(self, inputs):
        out = self.inner.compute(inputs)
        return {**out, "y3": out["y2"] * 3}

    def compute_partials(self, inputs):
        p = self.inner.compute_partials(inputs)
        return {**p, **{("y3", i): 3 * c for (o, i), c in p.items() if o == "y2"}}


def test_fused_downstream_disciplines_are_exactly_the_unfused_results_one_wave_less():
    pts = [_point(*p) for p in TRAJECTORY]
    plain, _ = _sequence(pts)
    fused, mda = _sequence(pts, fuse_downstream=True)
    for (p, wp), (f, wf) in zip(plain, fused):
        assert wf == wp - 1
        for v in ("y1", "y2", "obj"):
            assert f.values[v][0] == p.values[v][0]  # the same loop iterates: bit for bit
        for k, col in p.partials["sellar_obj"].items():
            assert f.partials["sellar_obj"][k][0] == col[0]
    discs = sellar_disciplines() + [_Tail2(), _ReadsLoopOnlyOutput()]
    discs[1] = _Dis2WithY3()
    m = MDA(InProcessEvaluator(discs), method="newton", fuse_downstream=True)
    w = [i for i, wave in enumerate(m.graph.waves) if any(m.graph.is_cyclic(c) for c in wave)][0]
    assert m.solver.downstream(("sellar1", "sellar2"), w) == ["sellar_obj"]
    res = m.run(_point(3.0, 1.0, 2.0))
    assert res.ok[0] and res.values["obj2"][0] == 2 * res.values["obj"][0]
    assert res.values["w"][0] == res.values["y2"][0] * 3 + 1


class _ObjFailsFar:
    """The objective, failing (NaN) while y2 is far from its converged value at (3, 1, 2)."""

    name, inputs, outputs = "sellar_obj", SellarObjective.inputs, SellarObjective.outputs

    def __init__(self, y2_near):
        self.inner, self.y2_near, self.calls = SellarObjective(), y2_near, 0

    def compute(self, inputs):
        self.calls += 1
        out = self.inner.compute(inputs)
        return {k: np.where(np.abs(inputs["y2"] - self.y2_near) > 1e-3, np.nan, v) for k, v in out.items()}


def test_a_fused_discipline_failing_before_convergence_does_not_fail_the_point_one_failing_at_it_does():
    ref = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", warm_start=False).run(_point(3.0, 1.0, 2.0))
    discs = sellar_disciplines()
    discs[2] = _ObjFailsFar(ref.values["y2"][0])
    m = MDA(InProcessEvaluator(discs), method="newton", fuse_downstream=True, warm_start=False)
    res = m.run(_point(3.0, 1.0, 2.0))
    assert discs[2].calls == res.iterations[0] > 1  # once per Newton step, the early ones failed
    assert res.ok[0] and res.values["obj"][0] == ref.values["obj"][0]
    discs[2] = _ObjFailsFar(ref.values["y2"][0] + 1.0)  # fails at the converged couplings too
    bad = MDA(InProcessEvaluator(discs), method="newton", fuse_downstream=True).run(
        {k: np.repeat(v, 2) for k, v in _point(3.0, 1.0, 2.0).items()})
    assert bad.ok.tolist() == [False, False] and "sellar_obj" in bad.messages[1]
    assert np.isnan(bad.values["obj"]).all() and np.isnan(bad.values["y1"]).all()


def test_config_keys(tmp_path):
    from pathlib import Path
    root = Path(__file__).resolve().parents[2]
    cfg = load_config(root / "examples" / "sellar" / "sellar_mdf_newton.yaml")
    assert cfg["mda"]["warm_start"] == "tangent" and cfg["mda"]["fuse_downstream"] is False
    raw = yaml.safe_load((root / "examples" / "sellar" / "sellar_mdf.yaml").read_text())
    for key, bad in (("warm_start", "sometimes"), ("fuse_downstream", "yes")):
        raw["mda"] = {"method": "newton", key: bad}
        raw["search_path"] = [str(root / "examples" / "sellar")]
        p = tmp_path / "c.yaml"
        p.write_text(yaml.safe_dump(raw))
        with pytest.raises(ValueError, match=f"mda.{key}"):
            load_config(p)
    raw["mda"] = {"method": "gauss_seidel", "warm_start": "tangent"}
    p.write_text(yaml.safe_dump(raw))
    with pytest.raises(ValueError, match="mda.warm_start tangent needs mda.method newton"):
        load_config(p)
    raw["mda"] = {"method": "newton", "warm_start": "tangent", "fuse_downstream": True}
    p.write_text(yaml.safe_dump(raw))
    assert load_config(p)["mda"]["warm_start"] == "tangent"


# ------------------------------------------------------------------ tangent prediction
def test_tangent_warm_start_equals_cold_to_the_tolerance_in_fewer_waves_than_plain_warm():
    pts = [_point(*p) for p in TRAJECTORY]
    cold, _ = _sequence(pts, warm_start=False)
    plain, _ = _sequence(pts)
    tangent, mda = _sequence(pts, warm_start="tangent")
    for (c, _), (t, _) in zip(cold, tangent):
        assert t.ok.all()
        for v in ("y1", "y2", "obj"):
            np.testing.assert_allclose(t.values[v], c.values[v], rtol=10 * TOL, atol=10 * TOL)
    assert sum(w for _, w in tangent) < sum(w for _, w in plain)
    assert tangent[-1][0].iterations[0] == 1  # the same design again: the prediction is the fixed point
    again, _ = _sequence(pts, warm_start="tangent")
    assert [r.values["y1"][0] for r, _ in again] == [r.values["y1"][0] for r, _ in tangent]
    # the stored tangent is dy/dx at the reference: against central differences of cold MDAs
    unknowns, xs, x_ref, S, y_ref = mda.solver.tangents[("sellar1", "sellar2")]
    cold_mda = MDA(InProcessEvaluator(sellar_disciplines()), method="newton", tolerance=1e-14, warm_start=False)
    for k, x in enumerate(xs):
        h = 1e-5
        hi = {n: np.array([x_ref[xs.index(n)] + (h if n == x else 0.0)]) for n in xs}
        lo = {n: np.array([x_ref[xs.index(n)] - (h if n == x else 0.0)]) for n in xs}
        rh, rl = cold_mda.run(hi), cold_mda.run(lo)
        for j, v in enumerate(unknowns):
            assert S[j, k] == pytest.approx((rh.values[v][0] - rl.values[v][0]) / (2 * h), rel=1e-6, abs=1e-8)


def test_tangent_falls_back_to_the_plain_warm_start_without_analytic_partials_and_needs_newton():
    from vector_toys import NoPartials
    pts = [_point(*p) for p in TRAJECTORY[:4]]
    discs = sellar_disciplines()
    discs[1] = NoPartials(discs[1])
    ev = InProcessEvaluator(discs)
    mda = MDA(ev, method="newton", tolerance=TOL, warm_start="tangent")
    for p in pts:
        assert mda.run(p).ok.all()
    assert mda.solver.tangents[("sellar1", "sellar2")] is None and mda.solver.warm[("sellar1", "sellar2")]
    with pytest.raises(ValueError, match="tangent needs method newton"):
        MDA(ev, method="gauss_seidel", warm_start="tangent")
