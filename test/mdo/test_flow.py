"""Data-flow MDA (bev_mdo.mdo.flow): which rows each discipline evaluates, error numbering, dispatch."""
import pytest
import numpy as np

from bev_mdo.config import load_config, resolve_disciplines
from bev_mdo.mdo import flow
from bev_mdo.mdo.discipline import Discipline
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA
from bev_mdo.testing import REPO
from flow_toys import chain  # test/mdo is on sys.path (conftest.py)


X = {"x": np.array([1.0, -1.0, 2.0, 3.0, 4.0]), "z": np.array([0.0, 0.0, 9.0, 1.0, 2.0])}


def test_failed_point_is_not_sent_downstream_and_errors_use_batch_indices():
    ev = InProcessEvaluator(chain())
    res = MDA(ev).run(X)
    assert res.ok.tolist() == [True, False, False, True, True]
    assert res.messages[1].startswith("square: ValueError") and "at point 1" in res.messages[1]
    # point 2 fails in 'plus' (third row of the 4 rows plus evaluates): named by its batch index
    assert res.messages[2].startswith("plus: non-finite output") and "at point 2" in res.messages[2]
    # square ran every point (point 1 failed inside it); plus skipped point 1; half skipped 1 and 2;
    # side depends on nothing that failed, so it ran all five
    assert ev.counts == {"square": 5, "plus": 4, "half": 3, "side": 5}
    np.testing.assert_array_equal(res.values["v"][[0, 3, 4]], 0.5 * (X["x"] ** 2 + X["z"])[[0, 3, 4]])
    assert np.isnan(res.values["v"][[1, 2]]).all() and np.isnan(res.values["w"][[1, 2]]).all()
    # a failed point keeps what does not depend on the failure: side's u, and square's y at point 2
    # (plus failed there); they were NaN, as was every output of a 21 t design, its motor speed too
    np.testing.assert_array_equal(res.values["u"], 2 * X["x"])
    assert np.isnan(res.values["y"][1]) and res.values["y"][2] == 4.0


def test_flow_equals_wave_analysis_on_good_points():
    cfg = load_config(REPO / "config" / "leaf_nedc.yaml")
    rng = np.random.default_rng(3)
    pts = {"motor_kw": rng.uniform(40, 120, 50), "gear_ratio": rng.uniform(1, 11, 50),
           "battery_kwh": rng.uniform(20, 30, 50)}
    a = MDA(InProcessEvaluator(resolve_disciplines(cfg))).run(pts)
    b = MDA(InProcessEvaluator(resolve_disciplines(cfg)), data_flow=False).run(pts)
    assert a.ok.all() and b.ok.all()
    for k in b.values:
        np.testing.assert_array_equal(a.values[k], b.values[k])


def test_parameters_reach_the_disciplines_that_declare_them():
    res = MDA(InProcessEvaluator(chain())).run({**X, "offset": np.full(5, 10.0)})
    np.testing.assert_array_equal(res.values["w"][[0, 3, 4]], (X["x"] ** 2 + X["z"] + 10.0)[[0, 3, 4]])


class _OwnFlow(InProcessEvaluator):
    """An evaluator with its own one-request data flow (like the ROS one), or None to decline."""

    def __init__(self, disciplines, accept):
        super().__init__(disciplines)
        self.accept, self.flows = accept, 0

    def evaluate_flow(self, names, request, n):
        if not self.accept:
            return None
        self.flows += 1
        producer = {v: d for d in names for v in self.specs[d].outputs}
        out = {}
        for d in names:
            src = flow.sources_of(self.specs[d].inputs, producer, d)
            up = {s: (out[s].outputs, out[s].ok) for s in set(src.values())}
            out[d], k = flow.run_flow_discipline(self.disciplines[d], request, up, src, n)
            self.counts[d] += k
        return out


def test_one_request_path_and_wave_fallback_agree():
    one = _OwnFlow(chain(), accept=True)
    waves = _OwnFlow(chain(), accept=False)
    a, b = MDA(one).run(X), MDA(waves).run(X)
    assert one.flows == 1 and one.waves == 0
    assert waves.flows == 0 and waves.waves == 3  # square+side, plus, half
    assert a.errors == b.errors and a.ok.tolist() == b.ok.tolist() and one.counts == waves.counts
    for k in a.values:
        np.testing.assert_array_equal(a.values[k], b.values[k])


def test_a_graph_with_a_loop_is_not_analysed_by_data_flow():
    from sellar import sellar_disciplines

    mda = MDA(InProcessEvaluator(sellar_disciplines()))
    assert not mda.data_flow


class InPlace(Discipline):
    """Scales its input in place (bad style, but it must behave the same on every transport)."""
    name, inputs, outputs = "in_place", ("x",), ("z",)

    def compute(self, inputs):
        x = inputs["x"]
        x *= 2.0
        return {"z": x + 1.0}


def test_compute_gets_writable_inputs_even_from_a_read_only_buffer():
    from bev_mdo.mdo.discipline import run_discipline

    x = np.frombuffer(np.array([1.0, 2.0]).tobytes())  # read-only, like a column decoded from a message
    assert not x.flags.writeable
    res = run_discipline(InPlace(), {"x": x})
    assert res.ok.all() and res.outputs["z"].tolist() == [3.0, 5.0]
    assert x.tolist() == [1.0, 2.0]  # the caller's buffer is untouched


def test_a_discipline_writing_into_its_inputs_does_not_change_the_mda():
    class Uses(Discipline):
        name, inputs, outputs = "uses", ("x", "z"), ("w",)

        def compute(self, inputs):
            return {"w": inputs["x"] + inputs["z"]}

    res = MDA(InProcessEvaluator([InPlace(), Uses()])).run({"x": np.array([1.0, 2.0])})
    assert res.values["x"].tolist() == [1.0, 2.0]
    assert res.values["w"].tolist() == [1.0 + 3.0, 2.0 + 5.0]


def test_the_in_process_evaluator_serves_evaluate_flow_by_the_same_rule():
    """evaluate_flow is part of the Evaluator protocol: in process it is flow_by_waves,
    the same rows, results and counts as the MDA's own wave-by-wave data flow; a loop is refused."""
    from bev_mdo.mdo.evaluator import Evaluator
    from sellar import sellar_disciplines

    assert "evaluate_flow" in Evaluator.__dict__
    cfg = load_config(REPO / "config" / "leaf_nedc.yaml")
    own, ref = InProcessEvaluator(resolve_disciplines(cfg)), InProcessEvaluator(resolve_disciplines(cfg))
    mda = MDA(ref)
    waves = mda._flow_waves
    names = [m for wave in waves for m in wave]
    rng = np.random.default_rng(3)
    request = {"motor_kw": rng.uniform(40, 120, 7), "gear_ratio": rng.uniform(5, 12, 7),
               "battery_kwh": rng.uniform(20, 60, 7)}
    request["motor_kw"][2] = -5.0  # a failing point, not sent downstream
    got = own.evaluate_flow(names, request, 7)
    want = flow.flow_by_waves(ref, ref.specs, waves, request, 7)
    assert list(got) == names and own.counts == ref.counts and own.waves == ref.waves
    for m in names:
        np.testing.assert_array_equal(got[m].ok, want[m].ok)
        for k in want[m].outputs:
            np.testing.assert_array_equal(got[m].outputs[k], want[m].outputs[k])
    assert not got["energy"].ok[2]
    sellar = InProcessEvaluator(sellar_disciplines())
    assert sellar.evaluate_flow(list(sellar.specs), {"x": np.ones(2), "z1": np.ones(2), "z2": np.ones(2)}, 2) is None


def test_flow_join_waits_for_every_source_then_gives_the_rows_to_evaluate():
    """The one join rule (FlowJoin) a discipline node applies to its sources' data-flow results."""
    join = flow.FlowJoin({"mass_kg": "mass", "speed": "motor"}, {"mass": {"mass_kg"}, "motor": {"speed"}}, keep=2)
    names = ["mass", "motor", "energy"]
    req = {"motor_kw": np.array([1.0, 2.0, 3.0])}
    assert join.add(("r", 1), "mass", {"mass_kg": np.array([10.0, 20.0, 30.0]), **req},
                    np.array([True, False, True]), names) is None and len(join) == 1
    got = join.add(("r", 1), "motor", {"speed": np.array([5.0, 6.0, 7.0]), **req}, np.array([True, True, False]),
                   names, extra="msg")
    assert len(join) == 0 and got.n == 3 and got.sources == {"mass_kg": "mass", "speed": "motor"}
    assert list(got.request) == ["motor_kw"] and got.extras["motor"] == "msg"  # forwarded columns only
    assert flow.source_rows(got.sources, got.up, got.n).tolist() == [True, False, False]
    # a source outside this MDA is not waited for
    only = join.add(("r", 2), "mass", {"mass_kg": np.ones(2)}, np.ones(2, bool), ["mass", "energy"])
    assert only is not None and only.sources == {"mass_kg": "mass"}


def test_flow_join_refuses_malformed_results_and_sources_that_disagree():
    join = flow.FlowJoin({"a": "s1", "b": "s2"}, {"s1": {"a"}, "s2": {"b"}}, keep=2)
    with pytest.raises(flow.FlowError):  # the coupling column is missing
        join.add(("r", 1), "s1", {"x": np.ones(2)}, np.ones(2, bool), ["s1", "s2", "d"])
    with pytest.raises(flow.FlowError):  # rows of another size than point_ok says
        join.add(("r", 1), "s1", {"a": np.ones(3)}, np.ones(2, bool), ["s1", "s2", "d"], n=2)
    assert len(join) == 0  # nothing malformed is kept
    join.add(("r", 1), "s1", {"a": np.ones(2)}, np.ones(2, bool), ["s1", "s2", "d"])
    with pytest.raises(flow.SourcesDisagree):
        join.add(("r", 1), "s2", {"b": np.ones(3)}, np.ones(3, bool), ["s1", "s2", "d"])
    # a rejected source evaluated nothing: the others decide the batch size
    join.add(("r", 2), "s1", {}, np.zeros(0, bool), ["s1", "s2", "d"], rejected=True)
    got = join.add(("r", 2), "s2", {"b": np.ones(2)}, np.ones(2, bool), ["s1", "s2", "d"])
    assert got.n == 2 and not flow.source_rows(got.sources, got.up, 2).any()
    assert got.rejected == ("s1",)  # named, so the consumer can reject too rather than answer no row


def test_flow_join_forgets_the_oldest_unfinished_mda_beyond_its_size():
    join = flow.FlowJoin({"a": "s1", "b": "s2"}, {"s1": {"a"}, "s2": {"b"}}, keep=2)
    for eid in (1, 2, 3):
        join.add(("r", eid), "s1", {"a": np.ones(1)}, np.ones(1, bool), ["s1", "s2", "d"])
    assert len(join) == 2
    assert join.add(("r", 1), "s2", {"b": np.ones(1)}, np.ones(1, bool), ["s1", "s2", "d"]) is None  # forgotten
    assert join.add(("r", 3), "s2", {"b": np.ones(1)}, np.ones(1, bool), ["s1", "s2", "d"]) is not None


def test_a_data_flow_request_with_a_column_no_discipline_reads_is_refused_not_dropped():
    """The same entry check on the data-flow path as on the wave path: named, every point failed."""
    cfg = load_config(REPO / "config" / "leaf_nedc.yaml")
    ev = InProcessEvaluator(resolve_disciplines(cfg))
    mda = MDA(ev)
    request = {"motor_kw": np.full(2, 80.0), "gear_ratio": np.full(2, 8.0), "battery_kwh": np.full(2, 24.0)}
    assert all(r.ok.all() for r in flow.evaluate_flow(ev, ev.specs, mda._flow_waves, request, 2).values())
    waves_before = ev.waves
    got = flow.evaluate_flow(ev, ev.specs, mda._flow_waves, {**request, "motr_kw": np.ones(2)}, 2)
    assert set(got) == set(ev.specs) and ev.waves == waves_before  # refused before any evaluation
    for name, res in got.items():
        assert not res.ok.any() and res.error == f"{name}: rejected: unknown inputs ['motr_kw']"
