"""User problems from the INSTALLED `bev-mdo` (no PYTHONPATH), from a clean clone-like layout:
the README's "Your own discipline" example as written, and the Sellar
example from any working directory. In process (no ROS): the module rule is the same over ROS
(test/ros/test_sellar_ros.py runs the example's nodes without a path to it)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parents[2]
BEV = REPO / ".venv" / "bin" / "bev-mdo"  # installed by scripts/setup.sh; missing = a failure, not a skip


@pytest.fixture(scope="module")
def clone(tmp_path_factory):
    """The tracked files of examples/ and config/, as a fresh clone has them (nothing else)."""
    root = tmp_path_factory.mktemp("clone")
    try:
        files = subprocess.run(["git", "ls-files", "examples", "config"], cwd=REPO, capture_output=True,
                               text=True, check=True).stdout.split()
    except (OSError, subprocess.CalledProcessError):
        files = [str(p.relative_to(REPO)) for d in ("examples", "config") for p in (REPO / d).rglob("*")
                 if p.is_file() and "__pycache__" not in p.parts]
    for f in files:
        (root / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / f, root / f)
    return root


def _bev(*argv, cwd):
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    return subprocess.run([str(BEV), *map(str, argv)], cwd=cwd, env=env, capture_output=True, text=True,
                          timeout=600)


def test_the_readme_user_discipline_example_runs_as_written(clone):
    raw = yaml.safe_load((clone / "config" / "leaf_nedc.yaml").read_text())
    # README, "Your own discipline": exactly these two config lines, added to the default problem
    readme = yaml.safe_load(
        'disciplines: [vehicle_mass, energy, range, acceleration, motor_speed, cost,\n'
        '              {name: top_speed, class: "examples.top_speed:TopSpeed", options: {motor_max_speed_rad_s: 1100}}]\n'
        'problem: {constraints: {top_speed_kmh: {lower: 150}}}\n')
    raw["disciplines"] = readme["disciplines"]
    raw["problem"]["constraints"].update(readme["problem"]["constraints"])
    (clone / "my.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    p = _bev("optimize", "my.yaml", "--transport", "inprocess", "--json", "--quiet", cwd=clone)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout)
    assert doc["feasible"] and doc["outputs"]["top_speed_kmh"] >= 150 - 1e-3
    assert doc["baseline"]["name"].startswith("Leaf")  # the Leaf table, through problem.baseline


def test_the_sellar_example_runs_from_any_working_directory(clone, tmp_path):
    cfg = clone / "examples" / "sellar" / "sellar_mdf.yaml"
    p = _bev("optimize", cfg, "--transport", "inprocess", "--json", "--quiet", cwd=tmp_path)
    assert p.returncode == 0, p.stderr
    doc = json.loads(p.stdout)
    assert doc["objective"] == pytest.approx(3.18339395, rel=1e-7) and doc["baseline"] is None
    assert doc["iterations"] == doc["result_iteration"]
    e = _bev("evaluate", cfg, "--set", "z1=1.977639,z2=0,x=0", "--json", "--transport", "inprocess", cwd=tmp_path)
    assert e.returncode == 0, e.stderr
    assert json.loads(e.stdout)["objective"]["value"] == pytest.approx(3.18339395, rel=1e-6)
    s = _bev("sensitivity", cfg, "--order", "1", "--json", "--transport", "inprocess", cwd=tmp_path)
    assert s.returncode == 0, s.stderr
    assert set(json.loads(s.stdout)["first_order"]) == {"obj", "y1", "y2"}


def test_a_module_that_cannot_be_imported_is_one_line(clone, tmp_path):
    raw = yaml.safe_load((clone / "examples" / "sellar" / "sellar_mdf.yaml").read_text())
    raw["disciplines"][0]["class"] = "sellar_disciplines_typo:SellarDis1"
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(raw))
    p = _bev("optimize", "c.yaml", "--transport", "inprocess", cwd=tmp_path)
    assert p.returncode == 2 and p.stdout == ""
    (line,) = p.stderr.strip().splitlines()
    assert "disciplines[0] (sellar1): cannot import module 'sellar_disciplines_typo'" in line
