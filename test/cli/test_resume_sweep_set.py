"""Resuming from a sweep's bag keeps what the sweep fixed with --set (a user trial: a sweep with
--set battery_kwh=24, resumed, let battery_kwh go free again to its lower bound, with nothing said)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from bev_mdo.cli import main

LEAF = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"


def test_resume_from_a_sweep_holds_its_set_values(tmp_path, capsys):
    assert main(["sweep", str(LEAF), "--doe", "lhs", "--samples", "12", "--set", "battery_kwh=24", "drag_area_m2=0.7",
                 "--transport", "inprocess", "--out", str(tmp_path / "sw"), "--no-plots"]) == 0
    capsys.readouterr()
    code = main(["resume", str(tmp_path / "sw"), "--transport", "inprocess", "--no-record", "--json"])
    out = capsys.readouterr()
    doc = json.loads(out.out)
    assert code == 0 and "keeping what the sweep fixed with --set: battery_kwh=24, drag_area_m2=0.7" in out.err
    assert set(doc["design"]) == {"motor_kw", "gear_ratio"}  # battery_kwh held, not optimised to its bound
    # the baseline is evaluated with the held values: its name says so (it read 'Leaf (80 kW, 7.94:1, 24 kWh)')
    assert doc["baseline"]["name"].endswith("with battery_kwh=24, drag_area_m2=0.7 held")
    assert main(["evaluate", str(LEAF), "--set", f"motor_kw={doc['design']['motor_kw']!r}",
                 f"gear_ratio={doc['design']['gear_ratio']!r}", "battery_kwh=24", "drag_area_m2=0.7",
                 "--transport", "inprocess", "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert doc["outputs"]["energy_wh_per_km"] == pytest.approx(again["outputs"]["energy_wh_per_km"], rel=1e-9)
    assert doc["outputs"]["range_km"] == pytest.approx(again["outputs"]["range_km"], rel=1e-9)
