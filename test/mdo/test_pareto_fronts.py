"""``bev-mdo pareto`` on two-objective test problems with analytic fronts (examples/pareto/: ZDT1
unconstrained, SRN and TNK constrained), in process; the same over ROS in test/ros/test_pareto_fronts_ros.py.
Tolerances and why: test/mdo/pareto_fronts.py."""
from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import yaml

from bev_mdo.cli import main
from bev_mdo.mdo.pareto import non_dominated
from bev_mdo.testing import REPO

from pareto_fronts import EXAMPLES, POP, RUNS, check_front


def _pareto(capsys, config, out, *extra):
    code = main(["pareto", str(config), "--out", str(out), "--transport", "inprocess", *map(str, extra)])
    cap = capsys.readouterr()
    assert code == 0, cap.err
    return cap


@pytest.mark.parametrize("seed", [1, 2])
@pytest.mark.parametrize("problem", sorted(RUNS))
def test_the_front_matches_the_analytic_one(tmp_path, capsys, problem, seed):
    out = tmp_path / problem
    cap = _pareto(capsys, EXAMPLES / f"{problem}.yaml", out, "--pop", POP, "--generations", RUNS[problem][0],
                  "--seed", seed)
    check_front(problem, out / "front.json")
    rows = list(csv.DictReader((out / "front.csv").open()))
    doc = json.loads((out / "front.json").read_text())
    assert len(rows) == len(doc["front"]) and float(rows[0]["f1"]) == pytest.approx(doc["front"][0]["f1"], rel=1e-9)
    assert doc["evaluations"] == POP * RUNS[problem][0] and doc["batches"] == RUNS[problem][0]
    assert (out / "front_f2_vs_f1.png").stat().st_size > 0 and (out / "bag").is_dir()
    assert "SM-SA" not in cap.err + cap.out  # a user problem is no BEV topology


def test_a_maximised_objective_is_reported_as_itself(tmp_path, capsys):
    """The ZDT1 front with f2 given as a maximised -f2: the same designs, -f2 reported as evaluated."""
    (tmp_path / "neg.py").write_text(
        "class Neg:\n    name = 'neg'\n    inputs = ('f2',)\n    outputs = ('minus_f2',)\n"
        "    units = {'f2': '1', 'minus_f2': '1'}\n"
        "    def compute(self, inputs):\n        return {'minus_f2': -inputs['f2']}\n")
    raw = yaml.safe_load((EXAMPLES / "zdt1.yaml").read_text())
    raw["search_path"] = [str(EXAMPLES)]
    raw["disciplines"].append({"name": "neg", "class": "neg:Neg"})
    raw["problem"]["objectives"] = ["f1", {"name": "minus_f2", "maximize": True}]
    cfg = tmp_path / "zdt1_max.yaml"
    cfg.write_text(yaml.safe_dump(raw, sort_keys=False))
    _pareto(capsys, cfg, tmp_path / "max", "--pop", 12, "--generations", 20, "--seed", 1, "--no-plots")
    _pareto(capsys, EXAMPLES / "zdt1.yaml", tmp_path / "min", "--pop", 12, "--generations", 20, "--seed", 1,
            "--no-plots")
    got, ref = (json.loads((tmp_path / d / "front.json").read_text()) for d in ("max", "min"))
    assert got["objectives"] == [{"name": "f1", "maximize": False}, {"name": "minus_f2", "maximize": True}]
    assert [r["f1"] for r in got["front"]] == [r["f1"] for r in ref["front"]]
    assert [r["minus_f2"] for r in got["front"]] == [-r["f2"] for r in ref["front"]]


def test_sellar_with_objectives_on_the_command_line(tmp_path, capsys):
    """Sellar MDF (a coupled MDA), obj and y1 from --objectives: a front, no topology, no traceback."""
    out = tmp_path / "sellar"
    cap = _pareto(capsys, REPO / "examples" / "sellar" / "sellar_mdf.yaml", out, "--objectives", "obj,y1",
                  "--pop", 12, "--generations", 5, "--no-plots")
    doc = json.loads((out / "front.json").read_text())
    F = np.array([[r["obj"], r["y1"]] for r in doc["front"]])
    assert len(F) and non_dominated(F).all()
    assert all(r["y1"] >= 3.16 and r["y2"] <= 24 for r in doc["front"])  # the problem's constraints hold
    assert "NSGA-II 12 x 5 over inprocess: obj, y1" in cap.err
    # history names the front.csv it wrote, not the topology study's pareto_<topology>.csv (and no empty topology)
    from bev_mdo.cli import main

    assert main(["history", str(out / "bag")]) == 1
    err = capsys.readouterr().err
    assert "the final fronts are in the front.csv beside the bag" in err and "topolog" not in err, err


@pytest.mark.parametrize("argv,msg", [
    (["--objectives", "obj"], "pareto needs two or more objectives"),
    (["--objectives", "obj,y9"], "objective 'y9' is not produced by any discipline"),
    (["--objectives", "obj,obj"], "--objectives names 'obj' twice"),
    ([], "pareto needs two or more objectives: list them in problem.objectives"),
])
def test_bad_objectives_exit_2_before_anything_is_written(tmp_path, capsys, argv, msg):
    code = main(["pareto", str(REPO / "examples" / "sellar" / "sellar_mdf.yaml"), "--out", str(tmp_path / "o"),
                 "--transport", "inprocess", *argv])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and msg in err, err
    assert not (tmp_path / "o").exists()


def test_the_topology_study_refuses_a_problem_without_bev_disciplines(tmp_path, capsys):
    code = main(["pareto", str(REPO / "examples" / "sellar" / "sellar_mdf.yaml"), "--topology", "DM-DA",
                 "--out", str(tmp_path / "o"), "--transport", "inprocess"])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "sellar_mdf.yaml: --topology and --all-topologies study the BEV problem's powertrain topologies" in err
    assert not (tmp_path / "o").exists()
