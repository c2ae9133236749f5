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


def _breakdown_config(tmp_path, extra: str = "") -> str:
    text = (REPO / "config" / "leaf_nedc.yaml").read_text().replace("energy_model: flat", "energy_model: breakdown")
    cfg = tmp_path / "breakdown.yaml"
    cfg.write_text(text + extra)
    return str(cfg)


def test_the_breakdown_note_is_said_only_where_it_can_be_and_true(tmp_path, capsys):
    """The review of the note: sensitivity (whose point holds no vehicle mass) ended 'KeyError: vehicle_mass_kg',
    exit 7; a failed design ended exit 2 'vehicle_mass_kg must be in [100, 20000] kg, got nan' instead of its own
    failure; with battery_loss_weight 1 the note said the battery rows were not in a total that held them."""
    cfg = _breakdown_config(tmp_path)
    assert main(["sensitivity", cfg, "--transport", "inprocess"]) == 0
    capsys.readouterr()
    assert main(["evaluate", cfg, "--set", "battery_loss_weight=1", "--json", "--transport", "inprocess"]) == 0
    (note,) = [n for n in json.loads(capsys.readouterr().out)["notes"] if n.startswith("energy by Table 5-1")]
    assert note.endswith("(the total holds the battery rows x battery_loss_weight 1)"), note
    sized = tmp_path / "sized.yaml"  # a 3000 km target: a 25 t car, past the models' 20 t (docs/thesis.md)
    text = open(cfg).read()
    for old, new in (("energy_model: breakdown", "energy_model: breakdown\ndisciplines: [vehicle_mass, energy, range, "
                      "acceleration, motor_speed, cost, {name: battery_sizing, options: {range_target_km: 3000}}]"),
                     ("    battery_kwh: {lower: 20, upper: 30,  initial: 24}\n", ""),
                     ("battery_sized_for_range: false", "battery_sized_for_range: true"),
                     ("design: {motor_kw: 80, gear_ratio: 7.94, battery_kwh: 24}", "design: {motor_kw: 80, gear_ratio: 7.94}")):
        assert old in text, old
        text = text.replace(old, new)
    sized.write_text(text)
    assert main(["evaluate", str(sized), "--transport", "inprocess"]) == 1  # its failure, exit 1, not a user error
    out, err = capsys.readouterr()
    assert "evaluation failed: energy: ValueError: vehicle_mass_kg must be in [100, 20000] kg, got 2" in out, out + err
