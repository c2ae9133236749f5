"""What ``bev-mdo pareto`` says of its designs and how it exits (in process): a design whose motor cannot
follow the drive cycle is infeasible (as optimize, evaluate and sweep judge it), failed evaluations are
counted and named (never a constraint violation), a run without a feasible design exits 1 naming the least
violated one, one objective is refused in every mode before anything runs, and the front's columns have
their declared units."""
import csv
import json
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from bev_mdo.cli import main

ROOT = Path(__file__).resolve().parents[2]
ARTEMIS = ROOT / "config" / "topologies_artemis.yaml"


def _bev(tmp_path, motor_kw=(10.0, 130.0)):
    """The chapter-4 problem on the NEDC (fast) without its margin constraints, motors down to 10 kW: many
    designs cannot follow the cycle."""
    raw = yaml.safe_load(ARTEMIS.read_text())
    raw["cycle"] = {"name": "nedc", "dt_s": 1.0}
    raw["problem"]["design_variables"]["motor_kw"].update(lower=motor_kw[0], upper=motor_kw[1])
    raw["problem"]["constraints"] = {k: v for k, v in raw["problem"]["constraints"].items() if "margin" not in k}
    p = tmp_path / "bev.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


# Binh-Korn split in two disciplines; the objective part fails by its option ``fail``: 'always', or above x1 = 4
MODULE = '''
import numpy as np

class Geom:
    name = "geom"
    inputs = ("x1", "x2")
    outputs = ("c1", "c2")
    units = {"x1": "m", "x2": "m", "c1": "m**2", "c2": "m**2"}
    def compute(self, i):
        return {"c1": (i["x1"] - 5) ** 2 + i["x2"] ** 2, "c2": (i["x1"] - 8) ** 2 + (i["x2"] + 3) ** 2}

class Obj:
    name = "obj"
    inputs = ("x1", "x2")
    outputs = ("f1", "f2")
    units = {"x1": "m", "x2": "m", "f1": "m**2", "f2": "m**2"}
    def __init__(self, fail=""):
        self.fail = fail
    def compute(self, i):
        if self.fail == "always":
            raise RuntimeError("my model is broken")
        f2 = (i["x1"] - 5) ** 2 + (i["x2"] - 5) ** 2
        if self.fail == "nan":
            f2 = np.where(i["x1"] > 4.0, np.nan, f2)
        return {"f1": 4 * i["x1"] ** 2 + 4 * i["x2"] ** 2, "f2": f2}
'''


def _bnh(tmp_path, fail="", constraints=None):
    (tmp_path / "bnh_disc.py").write_text(textwrap.dedent(MODULE))
    raw = {"name": "bnh", "search_path": [str(tmp_path)],
           "disciplines": [{"name": "geom", "class": "bnh_disc:Geom"},
                           {"name": "obj", "class": "bnh_disc:Obj", **({"options": {"fail": fail}} if fail else {})}],
           "problem": {"objectives": ["f1", "f2"],
                       "design_variables": {"x1": {"lower": 0, "upper": 5}, "x2": {"lower": 0, "upper": 3}},
                       "constraints": constraints or {"c1": {"upper": 25}, "c2": {"lower": 7.7}}}}
    p = tmp_path / "bnh.yaml"
    p.write_text(yaml.safe_dump(raw))
    return p


def _pareto(capsys, cfg, out, *extra, pop=10, generations=3):
    code = main(["pareto", str(cfg), "--pop", str(pop), "--generations", str(generations), "--no-plots",
                 "--out", str(out), "--transport", "inprocess", *extra])
    cap = capsys.readouterr()
    return code, cap.out, cap.err


def _rows(path):
    return list(csv.DictReader(path.open()))


def test_a_design_that_cannot_follow_the_cycle_is_not_on_the_front(tmp_path, capsys):
    """A trial's front of 40 'feasible' designs held 13 whose motor cannot follow the cycle (sweep --list on
    them: 13 infeasible); the study's cost pick was one. Each front design is feasible by sweep's judgement."""
    from bev_mdo.api.evaluate import batch

    cfg = _bev(tmp_path)
    code, out, _ = _pareto(capsys, cfg, tmp_path / "o", pop=20, generations=3)
    assert code == 0
    doc = json.loads((tmp_path / "o" / "front.json").read_text())
    design = {k: np.array([p[k] for p in doc["front"]]) for k in ("motor_kw", "gear_ratio", "battery_kwh")}
    judged = batch(cfg, design, "inprocess")  # sweep's judgement of the same designs
    assert doc["front"] and judged["feasible"].all(), judged["notes"]
    assert doc["cannot_follow_evaluations"] > 0
    assert f"note: {doc['cannot_follow_evaluations']} of 60 evaluated designs cannot follow the drive cycle" in out
    # the topology study's fronts (and so its picks and ranking) too
    code, out, _ = _pareto(capsys, cfg, tmp_path / "t", "--topology", "SM-SA", pop=20, generations=3)
    rows = _rows(tmp_path / "t" / "pareto_SM-SA.csv")
    design = {k: np.array([float(r[k]) for r in rows]) for k in ("motor_kw", "gear_ratio", "battery_kwh")}
    assert code == 0 and rows and batch(cfg, design, "inprocess")["feasible"].all()
    summary = json.loads((tmp_path / "t" / "summary.json").read_text())
    assert summary["outcome"]["SM-SA"]["cannot_follow_evaluations"] > 0


def test_every_evaluation_failed_exits_1_with_the_first_error(tmp_path, capsys):
    """It read 'no feasible design (least normalised constraint violation 1e+06)', exit 0: the penalty, not the
    discipline's error."""
    code, out, _ = _pareto(capsys, _bnh(tmp_path, "always"), tmp_path / "o")
    assert code == 1
    line = next(ln for ln in out.splitlines() if ln.startswith("front: "))
    assert line.startswith("front: no design: every one of the 30 evaluated designs failed (first: obj: "
                           "RuntimeError: my model is broken at point 0"), line
    assert "1e+06" not in out and "violation" not in out
    doc = json.loads((tmp_path / "o" / "front.json").read_text())
    assert doc["failed_evaluations"] == 30 and "my model is broken" in doc["first_error"]
    assert "least_violated" not in doc


def test_failed_evaluations_are_counted_beside_the_front(tmp_path, capsys):
    code, out, _ = _pareto(capsys, _bnh(tmp_path, "nan"), tmp_path / "o", pop=20, generations=3)
    doc = json.loads((tmp_path / "o" / "front.json").read_text())
    assert code == 0 and doc["front"] and doc["failed_evaluations"] > 0
    assert "non-finite output ['f2']" in doc["first_error"]
    assert f"; {doc['failed_evaluations']} of 60 evaluated designs failed (first: obj: non-finite output" in out


def test_no_feasible_design_exits_1_naming_the_least_violated_design(tmp_path, capsys):
    """It exited 0 with an empty front.csv and did not name the design that came closest."""
    code, out, _ = _pareto(capsys, _bnh(tmp_path), tmp_path / "o", "--constraint", "c1<=-1", pop=20,
                           generations=5)
    assert code == 1
    line = next(ln for ln in out.splitlines() if ln.startswith("front: "))
    assert line.startswith("front: no feasible design (least violated: x1="), line
    assert " breaks c1 <= -1 m**2: its c1 is " in line
    least = json.loads((tmp_path / "o" / "front.json").read_text())["least_violated"]
    (broken,) = least["constraints"]
    assert broken["output"] == "c1" and broken["limit"] == -1 and broken["unit"] == "m**2"
    x1, x2 = least["design"]["x1"], least["design"]["x2"]
    assert broken["value"] == pytest.approx((x1 - 5) ** 2 + x2 ** 2) and broken["value"] < 1.0  # near (5, 0)


@pytest.mark.parametrize("mode", [(), ("--all-topologies",), ("--topology", "DM-DA")])
def test_one_objective_is_refused_in_every_mode_before_any_evaluation(tmp_path, capsys, mode):
    """--all-topologies --objectives energy_wh_per_km ran 4 x 3000 evaluations where plain pareto refused."""
    code, out, err = _pareto(capsys, _bev(tmp_path), tmp_path / "o", *mode, "--objectives", "energy_wh_per_km")
    assert code == 2 and "pareto needs two or more objectives" in err and "gen 1" not in err
    assert not (tmp_path / "o").exists()


def test_the_fronts_columns_have_their_declared_units(tmp_path, capsys):
    code, _, _ = _pareto(capsys, _bnh(tmp_path), tmp_path / "o")
    doc = json.loads((tmp_path / "o" / "front.json").read_text())
    header = next(csv.reader((tmp_path / "o" / "front.csv").open()))
    assert code == 0 and doc["units"] == {k: "m" if k.startswith("x") else "m**2" for k in header}
