"""NSGA-II over the batched MDA (mdo/pareto.py) and ``bev-mdo pareto`` (cli/pareto.py)."""
import csv
import json

import numpy as np
import pytest

from bev_mdo.mdo.evaluator import InProcessEvaluator
from bev_mdo.mdo.formulations import MDF
from bev_mdo.mdo.mda import MDA
from bev_mdo.mdo.pareto import non_dominated, run_nsga2
from bev_mdo.mdo.problem import Problem


class Zdt1:
    """ZDT1 on two variables with a constraint output."""
    name = "zdt1"
    inputs = ("x1", "x2")
    outputs = ("f1", "f2", "s")
    parameters = {}

    def __init__(self):
        self.calls = []

    def compute(self, x):
        self.calls.append(len(x["x1"]))
        g = 1 + 9 * x["x2"]
        return {"f1": x["x1"], "f2": g * (1 - np.sqrt(x["x1"] / g)), "s": x["x1"] + x["x2"]}


def _zdt_form():
    d = Zdt1()
    ev = InProcessEvaluator([d])
    prob = Problem.from_config({"objective": "f1", "design_variables": {"x1": {"lower": 0, "upper": 1},
                                                                        "x2": {"lower": 0, "upper": 1}},
                                "constraints": {"s": {"lower": 0.2}}})
    return MDF(prob, ev, MDA(ev)), d, ev


def _brute_non_dominated(F):
    n = len(F)
    return np.array([not any(np.all(F[j] <= F[i]) and np.any(F[j] < F[i]) for j in range(n) if j != i)
                     for i in range(n)])


def test_non_dominated_matches_brute_force():
    rng = np.random.default_rng(0)
    for _ in range(20):
        F = rng.integers(0, 5, (30, 3)).astype(float)  # ties and duplicates on purpose
        np.testing.assert_array_equal(non_dominated(F), _brute_non_dominated(F))
    assert non_dominated(np.array([[1.0, 2.0], [2.0, 1.0], [2.0, 2.0]])).tolist() == [True, True, False]


def test_nsga2_one_batch_per_generation_and_front_is_non_dominated():
    form, disc, ev = _zdt_form()
    r = run_nsga2(form, ["f1", "f2"], pop_size=20, generations=15, seed=3)
    assert r.batches == 15 and r.evaluations == sum(disc.calls[:15])
    assert disc.calls[0] == 20  # the whole initial population in one compute() call
    assert len(r.X) >= 5
    assert non_dominated(r.F).all()
    assert np.all(r.values["s"] >= 0.2 - 1e-12)  # feasible only
    # no evaluated feasible point dominates a front point
    feas = r.archive_cv <= 0
    A = r.archive_F[feas]
    for f in r.F:
        assert not np.any(np.all(A <= f, axis=1) & np.any(A < f, axis=1))
    # ZDT1's true front is f2 = 1 - sqrt(f1) (x2 = 0): the front is closer to it than the initial population
    gap = (lambda F: F[:, 1] - (1 - np.sqrt(F[:, 0])))
    assert np.median(gap(r.F)) < 0.5 * np.median(gap(r.archive_F[:20]))


def test_the_fronts_hypervolume_says_whether_it_has_settled():
    """A 24 x 15 front was three designs, all dominated by the single-objective optimum, and nothing said the
    front had not settled. Each generation's hypervolume (in the last front's scale) is kept and a line says
    how much it grew over the last generations."""
    from bev_mdo.mdo.pareto import hypervolumes, settling_line

    last = np.array([[0.0, 1.0], [1.0, 0.0], [0.5, 0.5]])  # normalised already: reference point 1.1 each
    hv = hypervolumes([np.array([[1.0, 1.0]]), np.zeros((0, 2)), last])
    assert hv[0] == pytest.approx(0.1 * 0.1) and np.isnan(hv[1])
    assert hv[2] == pytest.approx(0.11 + 0.11 + 0.36 - 0.06 - 0.06 - 0.01 + 0.01)  # inclusion-exclusion
    assert hypervolumes([2 * last + 3, 2 * last + 3]) == pytest.approx([hv[2], hv[2]])  # scale-free
    assert settling_line(hv) == ("front hypervolume over the last 2 generations: from almost nothing (0.01 -> 0.46 "
                                 "in the last front's scale, no per cent); the front was still forming: more "
                                 "--generations (or a larger --pop) would extend the front")
    assert settling_line(hv[1:]).startswith("front hypervolume over the last 1 generations: from no feasible design")
    assert settling_line([0.5, 0.70, 0.703]) == "front hypervolume over the last 2 generations: +40.6 %; still " \
        "moving: more --generations (or a larger --pop) would extend the front"
    assert settling_line([0.5, 0.70, 0.703], last=1).endswith("+0.4 % (settled: within 1 %)")
    assert settling_line([0.0, 0.5]).startswith("front hypervolume over the last 1 generations: from 0 (every design")
    assert settling_line([0.4]) is None and settling_line([0.3, float("nan")]) is None
    form, _, _ = _zdt_form()
    r = run_nsga2(form, ["f1", "f2"], pop_size=20, generations=15, seed=3)
    assert len(r.hypervolume) == 15 and r.hypervolume[-1] > r.hypervolume[0] > 0
    assert len(r.front_sizes) == 15 and r.front_sizes[-1] == len(r.X)


def test_no_growth_in_per_cent_from_almost_nothing_or_on_a_tiny_front():
    """A trial's fronts of 1 to 13 designs read "+650.8 %" and "+4646.9 %": meaningless percentages."""
    from bev_mdo.mdo.pareto import settling_line

    hv = [0.0, 0.0, 0.0935, 0.3037, 0.3047, 0.4488, 0.4488, 0.7018]
    line = settling_line(hv)  # from 0.0935 (13 % of the last): almost nothing
    assert "%" not in line.split(";")[0] and "from almost nothing (0.0935 -> 0.702" in line
    tiny = settling_line([0.6, 0.65, 0.7, 0.71, 0.72, 0.7018], sizes=[1, 2, 3, 5, 8, 13])
    assert tiny.startswith("front hypervolume over the last 5 generations: 0.6 -> 0.702 on fronts of 1 and 13 "
                           "designs, too few for a growth in per cent")
    big = settling_line([0.6, 0.65, 0.7, 0.71, 0.72, 0.7018], sizes=[40] * 6)
    assert big.startswith("front hypervolume over the last 5 generations: +17.0 %; still moving")
    assert settling_line([float("nan"), 0.5], sizes=[0, 3]).endswith("from no feasible design; still moving: more "
                                                                     "--generations (or a larger --pop) would extend the front")


def test_more_generations_are_advised_only_where_the_front_grew():
    """'more --generations would extend the front' was said of a front of one design (leaf_nedc's energy and
    cost fall together) and of a front whose hypervolume fell."""
    from bev_mdo.mdo.pareto import settling_line

    more = "more --generations (or a larger --pop) would extend the front"
    one = settling_line([1.2077, 1.2090, 1.2095, 1.2095, 1.2095, 1.21], sizes=[1, 2, 4, 3, 4, 1])
    assert one.startswith("the front is one design: the objectives do not trade off") and more not in one
    fell = settling_line([0.70, 0.70, 0.69, 0.68, 0.67, 0.65], sizes=[40] * 6)
    assert fell.startswith("front hypervolume over the last 5 generations: -7.1 %; not settled") and more not in fell
    tiny_fell = settling_line([0.70, 0.65], sizes=[6, 5])
    assert "too few for a growth in per cent" in tiny_fell and "it fell" in tiny_fell and more not in tiny_fell
    assert settling_line([0.65, 0.70], sizes=[5, 6]).endswith(more)  # it grew: the advice stands
    assert settling_line([0.5, 0.70, 0.703]).endswith(more)


def test_failed_points_are_counted_and_have_no_violation():
    """A failed point's constraint value was pymoo's penalty 1e6, reported as 'least normalised constraint
    violation 1e+06'."""
    class HalfFails(Zdt1):
        def compute(self, x):
            out = super().compute(x)
            return {**out, "f2": np.where(x["x1"] > 0.5, np.nan, out["f2"])}

    ev = InProcessEvaluator([HalfFails()])
    prob = Problem.from_config({"objective": "f1", "design_variables": {"x1": {"lower": 0, "upper": 1},
                                                                        "x2": {"lower": 0, "upper": 1}}})
    r = run_nsga2(MDF(prob, ev, MDA(ev)), ["f1", "f2"], pop_size=12, generations=2, seed=1)
    failed = ~np.isfinite(r.archive_cv)
    assert r.failed == failed.sum() > 0 and (r.archive_X[failed, 0] > 0.5).all()
    assert "non-finite output ['f2']" in r.first_error and len(r.X) and r.least_violated is None


def test_a_design_the_run_rules_out_is_infeasible_and_named():
    """``batch_check`` (the run's judgement beyond its constraints, such as a motor that cannot follow the
    cycle) is one more constraint: such a design is never on the front, nor named as feasible."""
    form, _, _ = _zdt_form()
    r = run_nsga2(form, ["f1", "f2"], pop_size=12, generations=3, seed=1,
                  design_check=lambda v: ["cannot follow"] if v["x1"] < 0.5 else [],
                  batch_check=lambda v: np.asarray(v["x1"]) < 0.5)
    assert len(r.X) and (r.X[:, 0] >= 0.5).all() and r.cannot_follow > 0
    nothing = run_nsga2(form, ["f1", "f2"], pop_size=12, generations=2, seed=1, design_check=lambda v: ["no"],
                        batch_check=lambda v: np.ones(len(v["x1"]), bool))
    assert not len(nothing.X) and nothing.least_violated["cannot_follow"] == ["no"]


def test_nsga2_deterministic_per_seed():
    a = run_nsga2(_zdt_form()[0], ["f1", "f2"], pop_size=12, generations=4, seed=7)
    b = run_nsga2(_zdt_form()[0], ["f1", "f2"], pop_size=12, generations=4, seed=7)
    np.testing.assert_array_equal(a.F, b.F)


def test_on_front_every_generation_final_is_the_result():
    form, disc, ev = _zdt_form()
    fronts = []
    r = run_nsga2(form, ["f1", "f2"], pop_size=12, generations=5, seed=2,
                  on_front=lambda f, final: fronts.append((f, final)))
    assert [f.generation for f, _ in fronts] == [1, 2, 3, 4, 5] and r.generations == 5
    assert [final for _, final in fronts] == [False] * 4 + [True]
    evaluated = {row.tobytes() for row in r.archive_X}
    for f, _ in fronts:
        assert len(f.X) and non_dominated(f.F).all()
        assert all(row.tobytes() in evaluated for row in f.X)  # only designs NSGA-II evaluated
        assert np.all(f.values["s"] >= 0.2 - 1e-12)
        np.testing.assert_array_equal(np.column_stack([f.values["x1"], f.values["x2"]]), f.X)
        np.testing.assert_array_equal(np.column_stack([f.values["f1"], f.values["f2"]]), f.F)
    assert [f.evaluations for f, _ in fronts] == list(np.cumsum(disc.calls[:5]))
    last = fronts[-1][0]
    np.testing.assert_array_equal(last.X, r.X)
    np.testing.assert_array_equal(last.F, r.F)
    # the front's values are the evaluated ones, equal to a fresh analysis of the same designs
    again = form.analyse(r.X).values
    for k in ("f1", "f2", "s"):
        np.testing.assert_array_equal(r.values[k], again[k])
    assert disc.calls[:5] == [12] * 5 and len(disc.calls) == 6  # the result needed no extra batch


class Reach:
    """Cheap designs (x < 0.4) cannot do the job: their time is a continuation value from 1e4 up."""
    name = "reach"
    inputs = ("x",)
    outputs = ("cost", "time")
    parameters = {}

    def compute(self, v):
        x = v["x"]
        return {"cost": x, "time": np.where(x < 0.4, 1e4 + 100 * (0.4 - x), 1.0 / x)}


def test_objective_ceiling_keeps_designs_that_cannot_do_the_job_off_the_front():
    ev = InProcessEvaluator([Reach()])
    prob = Problem.from_config({"objective": "cost", "design_variables": {"x": {"lower": 0, "upper": 1}}})
    form = MDF(prob, ev, MDA(ev))
    bare = run_nsga2(form, ["cost", "time"], pop_size=20, generations=5, seed=2)
    assert (bare.F[:, 1] >= 1e4).any()  # without the ceiling the cheapest such design is on the front
    r = run_nsga2(form, ["cost", "time"], pop_size=20, generations=5, seed=2, ceilings={"time": 1e4, "other": 0.0})
    assert len(r.F) and (r.F[:, 1] < 1e4).all() and (r.X[:, 0] >= 0.4).all()
    assert ((r.archive_F[:, 1] >= 1e4) == (r.archive_cv > 0)).all()  # infeasible exactly there


def test_unknown_objective():
    with pytest.raises(ValueError, match="objective 'f9' is not produced"):
        run_nsga2(_zdt_form()[0], ["f1", "f9"], pop_size=8, generations=1)


# ---- CLI -------------------------------------------------------------------------------------

def _cli(argv):
    """``bev-mdo ARGV``, in process."""
    from bev_mdo.cli import main
    return main([*argv, "--transport", "inprocess"])


def _write_cfg(tmp_path, topology="SM-SA", drop=(), extra_dv=None, dt_s=1.0):
    import yaml
    from pathlib import Path

    raw = yaml.safe_load((Path(__file__).resolve().parents[2] / "config" / "topologies_artemis.yaml").read_text())
    raw["cycle"] = {"name": "nedc", "dt_s": dt_s}  # fast
    raw["vehicle"]["topology"] = topology
    for k in drop:
        raw["problem"]["design_variables"].pop(k)
    raw["problem"]["design_variables"].update(extra_dv or {})
    p = tmp_path / "cfg.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


OBJ = ("energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd")


def _bag_fronts(bag):
    """(topology, generation, final, run_id, objectives, {name: column}) of every ParetoFront, read with rosbags."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out = []
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == "/bev_mdo/pareto_front"]
        assert conns and conns[0].msgtype == "bev_mdo_msgs/msg/ParetoFront"
        for c, _, raw in reader.messages(connections=conns):
            m = reader.deserialize(raw, c.msgtype)
            n, names = int(m.designs.batch_size), list(m.designs.names)
            v = np.asarray(m.designs.values, float).reshape(len(names), n)  # column-major
            out.append((m.topology, int(m.generation), bool(m.final), m.run_id, list(m.objectives),
                        {k: v[j] for j, k in enumerate(names)}, int(m.evaluations)))
    return out


def check_bag_fronts(out, topologies, generations, pop):
    """The bag in ``out`` holds every generation's front per topology; each is feasible and
    non-dominated; the final one equals ``pareto_<T>.csv``. Returns the fronts."""
    from bev_mdo.studies.topologies import read_fronts

    fronts = _bag_fronts(out / "bag")
    assert [(t, g, f) for t, g, f, *_ in fronts] == [
        (t, g, g == generations) for t in topologies for g in range(1, generations + 1)]
    assert len({r for _, _, _, r, *_ in fronts}) == 1  # one run id
    summary = json.loads((out / "summary.json").read_text())
    assert fronts[0][3] == summary["run_id"]
    for t, g, final, _, objectives, cols, evaluations in fronts:
        assert objectives == list(OBJ) and evaluations == g * pop
        assert len(cols["energy_wh_per_km"]) <= pop
        if len(cols["energy_wh_per_km"]):
            F = np.column_stack([cols[k] for k in OBJ])
            assert non_dominated(F).all(), (t, g)
            assert np.all(cols["range_nedc_km"] >= 175.0), (t, g)  # feasible only
        if final:
            rows = list(csv.DictReader((out / f"pareto_{t}.csv").open()))
            assert set(rows[0]) == set(cols)  # every design variable and MDA output
            for k in cols:  # the CSV has 10 significant digits
                np.testing.assert_allclose([float(r[k]) for r in rows], cols[k], rtol=1e-9, atol=0, err_msg=k)
    ours = read_fronts(out / "bag")  # bev_mdo's own reader agrees with rosbags
    assert [(f["topology"], f["generation"], f["final"]) for f in ours] == [(t, g, f) for t, g, f, *_ in fronts]
    for f, (*_, cols, _) in zip(ours, fronts):
        assert f["designs"].keys() == cols.keys()
        for k in cols:
            np.testing.assert_array_equal(f["designs"][k], cols[k])
    return fronts


def test_cli_writes_front_csv_benchmark_and_plots(tmp_path):
    p = _write_cfg(tmp_path)
    out = tmp_path / "bag"
    assert _cli(["pareto", str(p), "--topology", "IWM-SA", "--generations", "2", "--pop", "8", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "pareto_IWM-SA.csv").open()))
    assert rows and "gear_ratio" not in rows[0] and "motor_kw" in rows[0]
    F = np.array([[float(r[k]) for k in ("energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd")]
                  for r in rows])
    assert non_dominated(F).all()
    assert all(float(r["range_nedc_km"]) >= 175 for r in rows)
    bench = list(csv.DictReader((out / "benchmark.csv").open()))
    assert bench[0]["topology"] == "IWM-SA" and float(bench[0]["kerb_kg"]) == pytest.approx(1521.16)
    s = json.loads((out / "summary.json").read_text())
    assert s["timing"]["IWM-SA"]["batches"] == 2 and len(s["timing"]["IWM-SA"]["hypervolume_by_generation"]) == 2
    assert (out / "fig_4_5_energy_accel.png").stat().st_size > 0 and (out / "fig_4_6_energy_cost.png").exists()
    fronts = check_bag_fronts(out, ["IWM-SA"], 2, 8)
    assert "gear_ratio" not in fronts[-1][5] and "motor_kw" in fronts[-1][5]


def test_cli_front_holds_no_design_that_cannot_reach_100_kmh(tmp_path):
    import yaml

    from bev_mdo.models.acceleration import NOT_REACHED_S

    # in-wheel motors without the energy model's margins: whether they follow the cycle is not checked, so
    # nothing else rules out a motor too small for 100 km/h (the cycle-follow check would: the NEDC reaches 120)
    p = _write_cfg(tmp_path, topology="IWM-SA", drop=("gear_ratio",),
                   extra_dv={"motor_kw": {"lower": 2, "upper": 10, "initial": 8}})
    raw = yaml.safe_load(p.read_text())
    raw["problem"]["constraints"] = {}
    raw["disciplines"] = [d if not (isinstance(d, dict) and d.get("name") == "energy") else "energy"
                          for d in raw["disciplines"]]
    p.write_text(yaml.safe_dump(raw))
    out = tmp_path / "front"
    assert _cli(["pareto", str(p), "--objectives", "powertrain_cost_usd,accel_time_0_100_s", "--generations", "3",
                 "--pop", "20", "--no-plots", "--out", str(out)]) == 0
    rows = list(csv.DictReader((out / "front.csv").open()))
    assert rows and all(float(r["accel_time_0_100_s"]) < NOT_REACHED_S for r in rows)
    first = _bag_fronts(out / "bag")[0][5]["accel_time_0_100_s"]  # every generation's front, not only the last
    assert len(first) and (first < NOT_REACHED_S).all()
    doc = json.loads((out / "front.json").read_text())  # the hypervolumes' reference point beside them
    assert doc["hypervolume_reference"]["point"] == [1.1, 1.1] and len(doc["hypervolume_by_generation"]) == 3
    assert doc["front_size_by_generation"][-1] == len(rows)


def test_cli_all_topologies_one_bag(tmp_path):
    from bev_mdo.models.topology import TOPOLOGIES

    out = tmp_path / "all"
    cfg = _write_cfg(tmp_path, dt_s=2.0)  # the NEDC range integration is most of the time
    assert _cli(["pareto", str(cfg), "--all-topologies", "--generations", "1", "--pop", "4",
                 "--no-plots", "--out", str(out)]) == 0
    fronts = check_bag_fronts(out, list(TOPOLOGIES), 1, 4)
    final = {t: cols for t, _, f, _, _, cols, _ in fronts if f}
    assert "motor_rear_kw" in final["DM-DA"] and "gear_ratio_rear" in final["DM-DA"]
    assert "motor_rear_kw" in final["IWM-DA"] and "gear_ratio" not in final["IWM-DA"]
    # the bag is not overwritten by a second run into the same directory
    assert _cli(["pareto", str(cfg), "--generations", "1", "--pop", "4", "--out", str(out)]) == 2
