"""The config's baseline says what its column does not: a design outside its bounds is infeasible (evaluate's
rule), a model parameter it sets is named beside the run's value; under optimize's table and in its JSON."""
from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import yaml

from bev_mdo.cli import main
from bev_mdo.config import RunConfig
from bev_mdo.sessions import analyse_baseline

CONFIG = Path(__file__).resolve().parents[2] / "config/leaf_nedc.yaml"


def _config(tmp_path, design: dict) -> str:
    raw = yaml.safe_load(CONFIG.read_text())
    raw["problem"]["baseline"]["design"] = design
    path = tmp_path / "leaf.yaml"
    path.write_text(yaml.safe_dump(raw))
    return str(path)


def _optimize(path: str, *argv) -> str:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        assert main(["optimize", path, "--transport", "inprocess", "--no-record", "--quiet", *argv]) == 0
    return buf.getvalue()


def test_a_baseline_outside_its_bounds_is_infeasible_with_evaluates_note(tmp_path):
    path = _config(tmp_path, {"motor_kw": 800, "gear_ratio": 7.94, "battery_kwh": 24})
    base = analyse_baseline(RunConfig.load(path))
    note = "motor_kw = 800 is outside its bounds [40, 120]: infeasible whatever the constraints say (evaluated as given)"
    assert base["feasible"] is False and base["notes"] == [note]
    assert all(c["satisfied"] for c in base["constraints"].values())  # its constraints alone would call it feasible
    out = _optimize(path)
    assert f"baseline {base['name']}: {note}" in out
    assert json.loads(_optimize(path, "--json"))["baseline"]["notes"] == [note]


def test_a_baseline_inside_its_bounds_has_no_notes():
    base = analyse_baseline(RunConfig.load(CONFIG))
    assert base["feasible"] is True and "notes" not in base


def test_a_parameter_the_baseline_sets_is_named_under_the_table(tmp_path):
    path = _config(tmp_path, {"drag_area_m2": 0.3, "motor_kw": 80, "gear_ratio": 7.94, "battery_kwh": 24})
    base = analyse_baseline(RunConfig.load(path))
    assert base["parameters"] == {"drag_area_m2": 0.3} and base["notes"] == ["drag_area_m2 = 0.3 (the run's 0.6412)"]
    assert f"baseline {base['name']}: drag_area_m2 = 0.3 (the run's 0.6412)" in _optimize(path)
