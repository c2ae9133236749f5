"""Per-point errors are data (EvalResult.point_errors: point index -> PointError), never text read
back: a failing point among several is named by its index in the caller's batch on every path
(one call, data flow, waves, a loop on fewer rows, Newton, shares joined)."""
import numpy as np
import pytest

from bev_mdo.mdo.discipline import Discipline, EvalResult, PointError, join_errors, run_discipline
from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.mda import MDA
from bev_mdo.mdo.vectors import ShapeError
from flow_toys import LOOP_X, Square, chain, loop  # test/mdo is on sys.path (conftest.py)

X = {"x": np.array([1.0, -1.0, 2.0, 3.0, 4.0]), "z": np.array([0.0, 0.0, 9.0, 1.0, 2.0])}


def test_one_call_names_each_failed_point_by_its_index():
    res = run_discipline(Square(), {"x": np.array([1.0, -2.0, 3.0, -4.0])})
    assert res.ok.tolist() == [True, False, True, False]
    assert res.point_errors == {1: PointError("square: ValueError: x must be >= 0", "x=-2"),
                                3: PointError("square: ValueError: x must be >= 0", "x=-4")}
    assert res.error == ("square: ValueError: x must be >= 0 at point 1 (x=-2); "
                         "square: ValueError: x must be >= 0 at point 3 (x=-4)")


def test_a_complex_output_fails_its_points_with_one_line_not_a_warning(recwarn):
    """It was cast to float with a numpy ComplexWarning on stderr: the imaginary part dropped, the point kept."""
    class Root(Discipline):
        name, inputs, outputs = "root", ("x",), ("y",)

        def compute(self, inputs):
            return {"y": np.sqrt(inputs["x"] + 0j)}

    res = run_discipline(Root(), {"x": np.array([-4.0, 9.0])})
    assert res.ok.tolist() == [False, False] and np.isnan(res.outputs["y"]).all()
    assert res.point_errors[0] == PointError("root: ValueError: output 'y' is complex, e.g. 2j: return real numbers",
                                             "x=-4")
    assert not [w for w in recwarn if issubclass(w.category, np.exceptions.ComplexWarning)]


@pytest.mark.parametrize("text", [np.array(["3.5", "4"]), ["3.5", 4.0], "3.5"])
def test_text_for_an_output_is_refused_naming_the_discipline_and_output(text):
    """It was converted without a word ('3.5' became 3.5)."""
    class Texty(Discipline):
        name, inputs, outputs, broadcast_outputs = "texty", ("x",), ("y",), ("y",)

        def compute(self, inputs):
            return {"y": text}

    with pytest.raises(ShapeError) as err:
        run_discipline(Texty(), {"x": np.array([1.0, 2.0])})
    assert str(err.value) == "discipline 'texty': output 'y' is text ('3.5'), not a number: return numbers"


def test_a_renumbered_result_moves_its_point_errors_and_text():
    res = run_discipline(Square(), {"x": np.array([1.0, -2.0])}).renumbered(np.array([5, 9]))
    assert list(res.point_errors) == [9] and res.error == "square: ValueError: x must be >= 0 at point 9 (x=-2)"


def test_shares_joined_keep_their_points_in_the_whole_batch():
    a = run_discipline(Square(), {"x": np.array([-1.0, 1.0])})
    b = run_discipline(Square(), {"x": np.array([2.0, -3.0])})
    hung = EvalResult({"y": np.full(2, np.nan)}, np.zeros(2, bool), "square: no answer")
    text, why = join_errors([(0, a), (2, b), (4, hung), (6, hung)])
    assert list(why) == [0, 3] and why[3].inputs == "x=-3"
    assert text == ("square: ValueError: x must be >= 0 at point 0 (x=-1); "
                    "square: ValueError: x must be >= 0 at point 3 (x=-3); square: no answer")


@pytest.mark.parametrize("data_flow", [True, False])
def test_a_feed_forward_mda_names_points_by_batch_index(data_flow):
    res = MDA(InProcessEvaluator(chain()), data_flow=data_flow).run(X)
    assert res.ok.tolist() == [True, False, False, True, True]
    assert res.messages[1] == "square: ValueError: x must be >= 0 at point 1 (x=-1)"
    # plus evaluates 4 rows (point 1 failed upstream); its third row is the batch's point 2
    assert res.messages[2] == "plus: non-finite output ['w'] at point 2 (y=4, z=9)"
    assert res.messages[0] == res.messages[3] == res.messages[4] == ""
    assert [(e.discipline, e.point, e.kind) for e in res.errors if e] == [("square", 1, "discipline"),
                                                                          ("plus", 2, "discipline")]


@pytest.mark.parametrize("method", ["gauss_seidel", "jacobi", "newton"])
def test_a_loop_on_fewer_rows_names_the_batch_point(method):
    res = MDA(InProcessEvaluator(loop()), method=method).run(LOOP_X)
    assert res.ok.tolist() == [False, True, False, False]
    assert res.messages[0].startswith("pre: non-finite output ['a'] at point 0")
    # the loop ran on rows [1, 2]: its failure at the second row is point 2 of the batch
    assert res.messages[2] == "loop_a: ValueError: a must be <= 5 at point 2 (a=7, y2=1)", res.messages[2]
    assert res.messages[3] == "loop_a: ValueError: a must be <= 5 at point 3 (a=8, y2=1)", res.messages[3]
    assert res.values["y1"][1] == pytest.approx(4.0 / 3.0)


def test_an_unknown_input_is_refused_in_process_as_a_node_refuses_it():
    """One entry check (mdo/discipline.py unknown_inputs) for every transport: a request naming a
    column its discipline does not read fails its points with the node's words, never silently."""
    import numpy as np

    from bev_mdo.mdo.discipline import readable, unknown_inputs
    from bev_mdo.mdo.evaluator import InProcessEvaluator
    from sellar import sellar_disciplines

    ev = InProcessEvaluator(sellar_disciplines())
    name = next(iter(ev.specs))
    inputs = {k: np.ones(3) for k in ev.specs[name].inputs}
    assert unknown_inputs(readable(ev.disciplines[name]), inputs) == []
    (res,) = ev.evaluate([(name, {**inputs, "not_an_input": np.ones(3)})])
    assert not res.ok.any() and res.error == f"{name}: rejected: unknown inputs ['not_an_input']"
    assert all(np.isnan(v).all() for v in res.outputs.values()) and ev.counts[name] == 3
    (good,) = ev.evaluate([(name, inputs)])
    assert good.ok.all()


def test_a_failed_point_is_named_by_the_runs_values_not_the_converted_ones():
    """A discipline taking a speed in km/h from a run in m/s failed with 'vmax_m_s=142.81' for 39.67 m/s:
    the converted value under the run's name and no unit."""

    class Hot:
        name, inputs, outputs = "hot", ("vmax_m_s",), ("t",)
        unit_conversions = {"vmax_m_s": (3.6, 0.0)}  # set at load when the units differ (mdo/units.py)

        def compute(self, inputs):
            if (inputs["vmax_m_s"] > 100.0).any():  # km/h here
                raise RuntimeError("too fast")
            return {"t": inputs["vmax_m_s"]}

    res = run_discipline(Hot(), {"vmax_m_s": np.array([10.0, 39.67])})
    assert list(res.ok) == [True, False] and res.outputs["t"][0] == pytest.approx(36.0)
    assert "vmax_m_s=39.67" in res.error and "142.8" not in res.error, res.error
