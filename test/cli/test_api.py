"""The Python API (bev_mdo.api, docs/api.md): the same optimum as the CLI, its example and its docs page
run as written, bad input raises InputError with the CLI's line, and ``import bev_mdo`` stays light."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from test.cli.test_readme import match_in_order

ROOT = Path(__file__).resolve().parents[2]
ENV = {**os.environ, "PYTHONPATH": str(ROOT), "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}


def cli(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bev_mdo", *argv], cwd=ROOT, env=ENV, capture_output=True,
                          text=True, timeout=600)


def same_optimum(api_x: dict, api_f: float, doc: dict) -> None:
    assert api_x.keys() == doc["design"].keys()
    for k, v in api_x.items():
        assert v == pytest.approx(doc["design"][k], rel=1e-9, abs=1e-9), k
    assert api_f == pytest.approx(doc["objective"], rel=1e-9)


@pytest.mark.parametrize("config", ["config/leaf_nedc.yaml", "examples/sellar/sellar_mdf.yaml"])
def test_the_api_optimum_is_the_cli_optimum(config):
    from bev_mdo import Study

    proc = cli("optimize", config, "--transport", "inprocess", "--json", "--no-record", "--quiet")
    assert proc.returncode == 0, proc.stderr[-2000:]
    doc = json.loads(proc.stdout)
    res = Study(ROOT / config).optimize(transport="inprocess")
    same_optimum(res.x, res.objective, doc)
    assert res.verdict == doc["verdict"] == "optimum"
    for name, c in doc["constraints"].items():
        assert res.constraints[name]["value"] == pytest.approx(c["value"], rel=1e-9, abs=1e-9), name
    assert res.first_order["verdict"] == doc["first_order"]["verdict"]


def test_the_example_gives_the_cli_optimum_with_the_same_constraint():
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "api" / "leaf_api.py"), "--json"], cwd=ROOT,
                          env=ENV, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    ex = json.loads(proc.stdout)
    ref = cli("optimize", "config/leaf_nedc.yaml", "--constraint", "range_km>=250", "--transport", "inprocess",
              "--json", "--no-record", "--quiet")
    assert ref.returncode == 0, ref.stderr[-2000:]
    doc = json.loads(ref.stdout)
    same_optimum(ex["x"], ex["objective"], doc)
    assert doc["constraints"]["range_km"]["lower"] == 250  # the constraint was applied on both sides
    assert doc["outputs"]["range_km"] == pytest.approx(250, rel=1e-6)
    table = subprocess.run([sys.executable, str(ROOT / "examples" / "api" / "leaf_api.py")], cwd=ROOT, env=ENV,
                           capture_output=True, text=True, timeout=600)
    assert table.returncode == 0 and "verdict: optimum" in table.stdout, table.stderr[-2000:]


def test_the_docs_page_runs_as_written(tmp_path):
    """Every python block of docs/api.md, in order, as one script from the repository's root; the
    text block under each must appear in what it printed, in order (``...``: anything)."""
    text = (ROOT / "docs" / "api.md").read_text(encoding="utf-8")
    pairs = re.findall(r"```python\n(.*?)```\s*```text\n(.*?)```", text, re.S)
    assert len(pairs) >= 6 and len(pairs) == len(re.findall(r"```python\n", text))
    script = tmp_path / "api_doc.py"
    marker = "=== block ==="
    script.write_text("\n".join(f"print({marker!r})\n{code}" for code, _ in pairs), encoding="utf-8")
    proc = subprocess.run([sys.executable, str(script)], cwd=ROOT, env=ENV, capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    printed = proc.stdout.split(marker + "\n")[1:]
    assert len(printed) == len(pairs)
    for (code, shown), got in zip(pairs, printed):
        missing = match_in_order(shown.splitlines(), got.splitlines())
        assert missing is None, f"docs/api.md block\n{code}\ndid not print {missing!r}; it printed:\n{got}"


@pytest.mark.parametrize("edit,argv", [
    (lambda s: s.bound("motr_kw", upper=100), ["--bound", "motr_kw=:100"]),
    (lambda s: s.constrain("range", lower=250), ["--constraint", "range>=250"]),
    (lambda s: s.objective("energy"), ["--objective", "energy"]),
])
def test_bad_input_raises_input_error_with_the_cli_line(edit, argv):
    from bev_mdo import InputError, Study

    with pytest.raises(InputError) as err:
        edit(Study(ROOT / "config" / "leaf_nedc.yaml"))
    proc = cli("optimize", "config/leaf_nedc.yaml", "--transport", "inprocess", "--no-record", *argv)
    assert proc.returncode == 2
    assert proc.stderr.strip() == f"bev-mdo optimize: error: {err.value}"
    assert "did you mean" in str(err.value)


@pytest.mark.parametrize("run", [
    lambda s: s.evaluate({"motor_kw": float("nan")}, transport="inprocess"),  # it returned NaN outputs
    lambda s: s.sweep(designs={"motor_kw": [80.0, float("inf")]}, transport="inprocess"),
    lambda s: s.sweep(designs={"motor_kw": [80.0]}, fixed={"battery_kwh": float("nan")}, transport="inprocess"),
    lambda s: s.sensitivity(at={"motor_kw": float("-inf")}, order=1, transport="inprocess"),
])
def test_a_design_value_that_is_not_finite_raises_input_error(run):
    from bev_mdo import InputError, Study

    with pytest.raises(InputError, match=r"=-?(nan|inf): a design value must be a finite number"):
        run(Study(ROOT / "config" / "leaf_nedc.yaml"))


@pytest.mark.parametrize("seed,said", [(-1, "seed -1: give a whole number >= 0"), (True, "seed True is not a whole number"),
                                       (1.5, "seed 1.5 is not a whole number")])
@pytest.mark.parametrize("run", [
    lambda s, seed: s.optimize(starts=2, seed=seed, transport="inprocess"),
    lambda s, seed: s.sweep("lhs", samples=2, seed=seed, transport="inprocess"),
    lambda s, seed: s.global_sensitivity(samples=8, seed=seed, transport="inprocess"),
    lambda s, seed: s.pareto(["obj", "y1"], generations=1, pop=4, seed=seed, transport="inprocess"),
])
def test_a_seed_is_checked_as_the_cli_checks_it(run, seed, said):
    """seed=-1 raised numpy's "expected non-negative integer" (naming nothing), seed=True ran as seed 1."""
    from bev_mdo import InputError, Study

    with pytest.raises(InputError) as err:
        run(Study(ROOT / "examples" / "sellar" / "sellar_mdf.yaml"), seed)
    assert str(err.value) == said
    if seed == -1:  # the CLI's line says the same
        proc = cli("optimize", "examples/sellar/sellar_mdf.yaml", "--seed", "-1", "--transport", "inprocess", "--no-record")
        assert proc.returncode == 2 and said.removeprefix("seed ") in proc.stderr


def test_a_bad_config_raises_input_error():
    from bev_mdo import InputError, Study

    with pytest.raises(InputError, match="no such config file"):
        Study(ROOT / "config" / "no_such.yaml")
    with pytest.raises(InputError, match="samples"):
        Study(ROOT / "config" / "leaf_nedc.yaml").sweep("sobol", samples=10, transport="inprocess")


@pytest.mark.parametrize("run,said", [
    (lambda s: s.evaluate([100, 7, 60], transport="inprocess"), "design must be a mapping"),  # TypeError before
    (lambda s: s.sweep(designs={"motor_kw": [110, 120], "gear_ratio": [6]}, transport="inprocess"),
     "all of the same length"),  # broadcast silently, then IndexError in rows()
    (lambda s: s.sweep(designs={"motor_kw": [80, 90]}, fixed={"motor_kw": 70}, transport="inprocess"),
     "fixed motor_kw is also varied"),  # the fixed value was dropped without a word
    (lambda s: s.sweep(designs={"motor_kw": []}, transport="inprocess"), "no design to evaluate"),  # empty result
    (lambda s: s.sweep(designs={}, transport="inprocess"), "no design to evaluate"),
    (lambda s: s.global_sensitivity("morris", samples=4, wrt=["motor_kw", 3], transport="inprocess"),
     "wrt must be a list of names"),
    # the problem's changes: a ValueError or TypeError of float(), and maximize read by truthiness ('no' maximised)
    (lambda s: s.bound("motor_kw", upper="abc"), r"^bound 'motor_kw': upper must be a finite number, got 'abc'$"),
    (lambda s: s.bound("motor_kw", upper=[1, 2]), "upper must be a finite number, got \\[1, 2\\]"),
    (lambda s: s.bound("motor_kw", lower=True), "lower must be a finite number, got True"),  # taken as 1
    (lambda s: s.bound("motor_kw", lower=float("nan")), "lower must be a finite number, got nan"),
    (lambda s: s.initial("motor_kw", None), r"^initial 'motor_kw' must be a finite number, got None$"),
    (lambda s: s.constrain("range_km", lower="abc"), "constrain 'range_km': lower must be a finite number"),
    (lambda s: s.objective(3), "objective: the output must be a name, got 3"),
    (lambda s: s.objective("range_km", maximize="no"), "maximize must be True or False, got 'no'"),
    (lambda s: s.objective("range_km", maximize=2), "maximize must be True or False, got 2"),
    # a list to evaluate reached float() as a TypeError; None was named nan (a user trial)
    (lambda s: s.evaluate({"motor_kw": [60, 80]}, transport="inprocess"),
     r"^motor_kw=\[60, 80\]: evaluate takes one design, a number per name; sweep\(designs=...\) evaluates many$"),
    (lambda s: s.evaluate({"motor_kw": None}, transport="inprocess"), r"^motor_kw=None: must be a number$"),
    (lambda s: s.sweep(designs={"motor_kw": [60, None]}, transport="inprocess"), r"motor_kw=\[60, None\]: must be a number"),
    (lambda s: s.sensitivity(at={"motor_kw": [60, 80]}, transport="inprocess"), r"--at motor_kw=\[60, 80\]: the design"),
    # a misspelt keyword: TypeError naming OptimizeOptions.__init__
    (lambda s: s.optimize(transport="inprocess", instance=2), r"instance: unknown key of optimize\(\); did you mean 'instances'"),
    # a count that is not a whole number: starts=2.9 ran 2 starts, "3" ran 3, True ran 1; samples=2.5 a bare TypeError
    (lambda s: s.optimize(starts=2.9, transport="inprocess"), r"^starts 2.9 is not a whole number$"),
    (lambda s: s.optimize(starts="3", transport="inprocess"), r"^starts '3' is not a whole number$"),
    (lambda s: s.optimize(starts=True, transport="inprocess"), r"^starts True is not a whole number$"),
    (lambda s: s.sweep("lhs", samples=2.5, transport="inprocess"), r"^samples 2.5 is not a whole number$"),
    (lambda s: s.global_sensitivity("morris", samples=4.0, transport="inprocess"), r"^samples 4.0 is a float: give it as an int \(4\)$"),
    (lambda s: s.sensitivity(order=1.0, transport="inprocess"), r"^order 1.0 is a float: give it as an int \(1\)$"),
    (lambda s: s.pareto(["energy_wh_per_km", "range_km"], generations=1.5, pop=4, transport="inprocess"),
     r"^generations 1.5 is not a whole number$"),
    (lambda s: s.pareto(["energy_wh_per_km", "range_km"], generations=1, pop="4", transport="inprocess"),
     r"^pop '4' is not a whole number$"),
    # a design value as text or a bool: "80" was read as 80, True as 1 (a bound refused them)
    (lambda s: s.evaluate({"motor_kw": "80"}, transport="inprocess"), r"^motor_kw='80': must be a number$"),
    (lambda s: s.evaluate({"motor_kw": True}, transport="inprocess"), r"^motor_kw=True: must be a number$"),
    (lambda s: s.sweep(designs={"motor_kw": ["60", "80"]}, transport="inprocess"), r"^designs motor_kw=\['60', '80'\]: must be a number$"),
    (lambda s: s.sweep(designs={"motor_kw": [60]}, fixed={"battery_kwh": "30"}, transport="inprocess"),
     r"^fixed battery_kwh='30': must be a number$"),
    (lambda s: s.sensitivity(at={"motor_kw": "80"}, order=1, transport="inprocess"), r"^--at motor_kw='80': must be a number$"),
    (lambda s: s.optimize(x0={"motor_kw": "80"}, transport="inprocess"), r"^x0 motor_kw='80': must be a number$"),
    (lambda s: s.optimize(x0=[80, 8, 24], transport="inprocess"), r"^x0 must be a mapping of names to values, got list$"),
    # transport= anything but a name or a Transport ran over ROS (the default), checked before the rest
    (lambda s: s.optimize(starts=0, transport={"transport": "inprocess"}),
     r"^transport must be a name \('ros' or 'inprocess'\) or a Transport, got \{'transport': 'inprocess'\}$"),
    (lambda s: s.evaluate({"motor_kw": float("nan")}, transport=None), r"^transport must be a name .* got None$"),
    (lambda s: s.sweep("lhs", samples=0, transport=5), r"^transport must be a name .* got 5$"),
    (lambda s: s.sensitivity(rel_step="big", transport="inprocess"), r"^rel_step must be a finite number, got 'big'$"),
    (lambda s: s.optimize(callback=5, transport="inprocess"),
     r"^callback must be a function of one iteration record, got 5$"),
])
def test_arguments_of_the_wrong_kind_raise_input_error(run, said):
    from bev_mdo import InputError, Study

    with pytest.raises(InputError, match=said):
        run(Study(ROOT / "config" / "leaf_nedc.yaml"))
    with pytest.raises(InputError, match="a study's config is a YAML file or a mapping, got int"):
        Study(42)


def test_one_name_is_taken_where_a_list_of_names_is_asked():
    """wrt="motor_kw" was iterated by character ("unknown variable or parameter 'm'")."""
    from bev_mdo import Study

    r = Study(ROOT / "config" / "leaf_nedc.yaml").sensitivity(wrt="motor_kw", order=1, transport="inprocess")
    assert list(r.wrt) == ["motor_kw"]


def test_importing_bev_mdo_and_naming_the_api_loads_no_numpy_and_no_ros():
    code = ("import sys, bev_mdo; bev_mdo.Study; bev_mdo.OptimizeResult; bev_mdo.ModelFailed; "
            "print(sorted(m for m in ('numpy', 'scipy', 'rclpy', 'bev_mdo.cli') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stdout + out.stderr


def test_results_as_tables(monkeypatch):
    from bev_mdo import Study

    study = Study(ROOT / "config" / "leaf_nedc.yaml")
    point = study.evaluate({"motor_kw": 80, "gear_ratio": 8, "battery_kwh": 24}, transport="inprocess")
    rows = point.rows()
    assert [r["name"] for r in rows[:3]] == ["motor_kw", "gear_ratio", "battery_kwh"]
    assert {r["role"] for r in rows} == {"design", "output", "objective"}
    assert point.to_dict()["outputs"]["range_km"] == point.outputs["range_km"]
    monkeypatch.setitem(sys.modules, "pandas", None)  # as without pandas installed
    with pytest.raises(ModuleNotFoundError, match="needs pandas"):
        point.to_dataframe()
    grid = study.sweep(designs={"motor_kw": [40, 80]}, transport="inprocess")
    assert [r["feasible"] for r in grid.rows()] == [False, True]  # 40 kW misses the 0-100 km/h limit
    assert grid.best()["motor_kw"] == 80


def _sellar_mapping(**edits) -> dict:
    import yaml

    raw = yaml.safe_load((ROOT / "examples" / "sellar" / "sellar_mdf.yaml").read_text(encoding="utf-8"))
    return {**raw, "search_path": [str(ROOT / "examples" / "sellar")], **edits}


def test_a_study_keeps_its_mapping_as_it_was_built():
    """A shallow copy: a later edit of the caller's nested dict reached the study at its next change."""
    from bev_mdo import Study

    raw = _sellar_mapping()
    study = Study(raw)
    raw["problem"]["design_variables"]["z1"]["upper"] = 3.0  # building a variant from the same dict
    raw["problem"]["constraints"]["y2"]["upper"] = 1.0
    study.constrain("y1", lower=3.16)
    assert study.config["problem"]["design_variables"]["z1"]["upper"] == 10
    assert study.config["problem"]["constraints"]["y2"]["upper"] == 24


@pytest.mark.parametrize("domain_id", ["x", 300, -1, True])
def test_a_transport_refuses_a_domain_id_that_is_no_ros_domain_when_made(domain_id):
    """It was accepted and refused only at the run, as the config's ros.domain_id."""
    from bev_mdo import InputError, Transport

    with pytest.raises(InputError) as err:
        Transport(domain_id=domain_id)
    assert str(err.value) == f"domain_id must be an integer in [0, 232], got {domain_id!r}"
    assert Transport(domain_id=232).domain_id == 232


def test_a_transport_takes_a_numpy_integer_domain_id_as_counts_and_seeds_do():
    """Transport(domain_id=np.int64(5)) was refused, 'got np.int64(5)', while counts and seeds take numpy integers."""
    import numpy as np

    from bev_mdo import InputError, Transport

    got = Transport(domain_id=np.int64(5)).domain_id
    assert got == 5 and type(got) is int
    with pytest.raises(InputError, match=r"domain_id must be an integer in \[0, 232\], got 300"):
        Transport(domain_id=np.int16(300))


def test_ctrl_c_during_a_run_raises_on_with_what_its_bag_holds(tmp_path):
    """KeyboardInterrupt came out bare; it carries the lines the CLI prints (what the bag holds, how to resume),
    and a later run without a bag does not name the earlier run's."""
    from bev_mdo import Study

    calls = []

    def stop_at_third(record):
        calls.append(record)
        if len(calls) == 3:
            raise KeyboardInterrupt

    bag = tmp_path / "b"
    study = Study(ROOT / "config" / "leaf_nedc.yaml")
    with pytest.raises(KeyboardInterrupt) as stopped:
        study.optimize(transport="inprocess", bag=str(bag), callback=stop_at_third)
    assert stopped.value.__notes__ == [
        "bev-mdo: interrupted",
        f"bev-mdo: bag {bag}: 3 iteration records, every finished iteration (bev-mdo history {bag}; "
        f"bev-mdo resume {bag} goes on from the last)"]
    calls.clear()
    with pytest.raises(KeyboardInterrupt) as again:
        study.optimize(transport="inprocess", callback=stop_at_third)
    assert again.value.__notes__ == ["bev-mdo: interrupted"]


def test_the_optimize_result_says_the_verdicts_a_run_gives():
    """It listed 'not_converged' and an ``active`` attribute; neither exists."""
    from bev_mdo import OptimizeResult
    from bev_mdo.mdo import first_order

    doc = " ".join(OptimizeResult.__doc__.split())
    for verdict in (first_order.OPTIMUM, first_order.STOPPED, first_order.NO_PROGRESS, first_order.INFEASIBLE):
        assert f'"{verdict}"' in doc
    assert "not_converged" not in doc and "``active`` the" not in doc


def test_a_note_of_study_evaluate_names_the_api_not_the_command(capsys):
    from bev_mdo import Study

    Study(ROOT / "config" / "leaf_nedc.yaml").evaluate({"motor_kw": 200}, transport="inprocess")
    assert capsys.readouterr().err.strip() == (
        "bev_mdo Study.evaluate: note: motor_kw = 200 is outside its bounds [40, 120] (evaluated as given)")


def test_the_seed_seeds_differential_evolution_when_its_options_give_none():
    """optimize(seed=7) left differential_evolution at its rng 0 (the same x as seed 0)."""
    from bev_mdo import Study

    def de(run_seed, **options):
        engine = {"name": "differential_evolution", "options": {"maxiter": 2, "popsize": 5, **options}}
        return Study(_sellar_mapping(optimizer=engine)).optimize(seed=run_seed, transport="inprocess")

    zero, seven, own = de(0), de(7), de(0, seed=7)
    assert zero.x != seven.x
    assert seven.x == own.x and seven.objective == own.objective  # the same draws as the option's seed 7
    assert de(3, seed=7).x == own.x  # the options' own seed wins


def test_a_doe_beside_given_designs_is_refused_not_ignored():
    """sweep("sobol", samples=32, designs=...) evaluated the 3 given designs, with no word of the DOE asked for."""
    from bev_mdo import InputError, Study

    study = Study(ROOT / "config" / "leaf_nedc.yaml")
    with pytest.raises(InputError, match=r"^sweep: doe='sobol' and designs= given: .*give one$"):
        study.sweep("sobol", samples=32, designs={"motor_kw": [60.0, 80.0, 100.0]}, transport="inprocess")
    assert len(study.sweep(samples=4, transport="inprocess").rows()) == 4  # no doe, no designs: lhs


def test_a_result_and_a_study_are_not_changed_through_what_they_hand_out():
    """A library-user trial: editing `to_dict()` changed the result (`o.x`, its verdict), and editing `study.config`
    showed a config its runs did not use."""
    from bev_mdo import Study

    study = Study(_sellar_mapping())
    r = study.evaluate({"z1": 5.0, "z2": 2.0, "x": 1.0}, transport="inprocess")
    d = r.to_dict()
    d["design"]["z1"], d["constraints"]["y1"]["value"] = -1.0, 0.0
    assert r.design["z1"] == 5.0 and r.to_dict()["constraints"]["y1"]["value"] == r.constraints["y1"]["value"] != 0
    study.config["problem"]["objective"] = "y1"  # a copy: the study's own is as built
    assert study.config["problem"]["objective"] == "obj" and study.config.problem.objective == "obj"


def test_a_misspelt_argument_is_an_input_error_with_the_nearest_one():
    """A library-user trial: optimize(formulaton=...) said 'did you mean'; evaluate, sweep, bound, ... raised a plain
    TypeError with no hint."""
    from bev_mdo import Study
    from bev_mdo.api import InputError

    study = Study(_sellar_mapping())
    for call, said in ((lambda: study.evaluate(desing={}), "evaluate() has no argument 'desing'; did you mean 'design'?"),
                       (lambda: study.bound("x", lowr=1), "bound() has no argument 'lowr'; did you mean 'lower'?"),
                       (lambda: study.sweep(sample=3), "sweep() has no argument 'sample'; did you mean 'samples'?"),
                       (lambda: study.sensitivity(order=1, wrt=["x"], rel_stp=1e-4), "did you mean 'rel_step'?")):
        with pytest.raises(InputError) as e:
            call()
        assert said in str(e.value) and "\n" not in str(e.value)


def test_a_vector_design_variable_given_whole_or_bare_says_how_to_give_it():
    """A library-user trial: evaluate({"t": [1, 2, 0.5]}) pointed at sweep(designs=...), which would take the list as
    three designs; evaluate({"t": 1}) said 'neither a design variable nor a discipline parameter; (unknown ...'."""
    from bev_mdo import Study
    from bev_mdo.api import InputError

    study = Study(ROOT / "examples" / "sellar_vector.yaml")
    for design, said in (({"z": [1.0, 2.0]}, "z=[1.0, 2.0]: a vector of 2 elements: give each, z[0] .. z[1]"),
                         ({"z": 1.0}, "design.z: a vector of 2 elements: give each, z[0] .. z[1]"),
                         ({"zz": 1.0}, "design.zz: neither a design variable nor a discipline parameter; unknown ")):
        with pytest.raises(InputError) as e:
            study.evaluate(design, transport="inprocess")
        assert str(e.value).startswith(said), str(e.value)


def test_plots_leave_the_callers_matplotlib_as_they_found_it(tmp_path):
    """A library call that draws (a Pareto front's plots, a bag's report) chose the Agg backend and turned the
    axis offset off for the rest of the caller's session, and left its figures registered with pyplot."""
    code = f"""
import sys, matplotlib
matplotlib.use("svg")
matplotlib.rcParams["axes.formatter.useoffset"] = True
from bev_mdo import Study
from bev_mdo.bag.report import report
study = Study({str(ROOT / "config" / "leaf_nedc.yaml")!r})
study.optimize(bag={str(tmp_path / "bag")!r}, transport="inprocess")
written = report({str(tmp_path / "bag")!r})
study.pareto(objectives=["energy_wh_per_km", "accel_time_0_100_s"], generations=2, pop=8,
             out={str(tmp_path / "front")!r}, plots=True, transport="inprocess")
print(sum(str(p).endswith(".png") for p in written), matplotlib.get_backend(),
      matplotlib.rcParams["axes.formatter.useoffset"], "matplotlib.pyplot" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=ENV, capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-3000:]
    pngs, backend, offset, pyplot = out.stdout.split()[-4:]
    assert int(pngs) >= 2 and (backend, offset, pyplot) == ("svg", "True", "False"), out.stdout
    assert list((tmp_path / "front").glob("front_*.png"))
