"""The SSBJ example (examples/ssbj/, docs/ssbj.md) as a user runs it: the installed ``bev-mdo``,
from another working directory, no PYTHONPATH; in process (over ROS: test/ros/test_ssbj_ros.py)."""
from __future__ import annotations

import csv
import json
import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
BEV = REPO / ".venv" / "bin" / "bev-mdo"
EXAMPLE = REPO / "examples" / "ssbj"
pytestmark = pytest.mark.skipif(not BEV.exists(), reason="bev-mdo is not installed in .venv (run scripts/setup.sh)")


def _bev(*argv, cwd):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run([str(BEV), *map(str, argv)], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)


def test_ssbj_idf_optimize_and_history_from_any_working_directory(tmp_path):
    bag = tmp_path / "bag"
    p = _bev("optimize", EXAMPLE / "ssbj_idf.yaml", "--transport", "inprocess", "--json", "--quiet", "--bag", bag,
             cwd=tmp_path)
    assert p.returncode == 0, p.stderr[-2000:]
    doc = json.loads(p.stdout)
    assert doc["feasible"] and doc["maximize"] and doc["baseline"] is None
    assert doc["objective"] == pytest.approx(3963.3800123, abs=1e-3)  # the range itself, not its negation
    assert doc["design"]["x_shared[1]"] == pytest.approx(60000.0)
    h = _bev("history", bag, "--csv", tmp_path / "h.csv", cwd=tmp_path)
    assert h.returncode == 0, h.stderr
    rows = list(csv.DictReader((tmp_path / "h.csv").open()))
    assert len(rows) == doc["iterations"] + 1
    assert float(rows[-1]["objective"]) == pytest.approx(doc["objective"], rel=1e-12)
    assert {"design.x_shared[5]", "design.x_1[1]", "design.x_3", "constraint.g_3[2]"} <= set(rows[0])


def test_ssbj_check_partials_at_the_start_design(tmp_path):
    p = _bev("check-partials", EXAMPLE / "ssbj_mdf.yaml", "--json", cwd=tmp_path)
    assert p.returncode == 0, p.stdout[-2000:] + p.stderr[-2000:]
    doc = json.loads(p.stdout)
    assert doc["ok"] and [d["discipline"] for d in doc["disciplines"]] == ["structure", "aerodynamics",
                                                                           "propulsion", "mission"]
