"""What the energy discipline says about one design beside its number."""
from __future__ import annotations

import json

from bev_mdo.cli import main
from bev_mdo.testing import REPO

# Table 5-1, NEDC, 40 % regeneration (kWh/100 km): aerodynamic, rolling, inertia, recovery, transmission, motor, total
TABLE_5_1_NEDC_40 = (4.03, 3.05, 4.95, -1.98, 0.42, 2.16, 12.63)


def test_the_breakdown_model_gives_its_table_5_1_rows(tmp_path, capsys):
    """A thesis trial: docs/thesis.md compares Table 5-1 row by row, but no command printed the rows, only the total."""
    text = (REPO / "config" / "leaf_nedc.yaml").read_text()
    assert "energy_model: flat" in text
    cfg = tmp_path / "breakdown.yaml"
    cfg.write_text(text.replace("energy_model: flat", "energy_model: breakdown"))
    assert main(["evaluate", str(cfg), "--set", "motor_kw=80,battery_kwh=24", "--json", "--transport", "inprocess"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert abs(report["outputs"]["vehicle_mass_kg"] - 1590.0) < 1e-9  # Table 5-1's M
    (note,) = [n for n in report["notes"] if n.startswith("energy by Table 5-1's rows, kWh/100 km: ")]
    values = [float(part.rsplit(" ", 1)[1]) for part in note.split(": ", 1)[1].split(" (")[0].split(", ")]
    for ours, thesis in zip(values[:7], TABLE_5_1_NEDC_40):
        assert abs(ours - thesis) <= 0.01 * abs(thesis) + 0.005, (note, thesis)
    assert abs(values[6] * 10 - report["outputs"]["energy_wh_per_km"]) < 0.01  # the total is the model's energy
