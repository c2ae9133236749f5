"""A fleet file whose column medians lie far from measured BEVs' (a unit mix-up: Wh/mi, lb, lbf) is read with a
note naming the column, its median and the likely unit; the shipped fleet gives none."""
from __future__ import annotations

import contextlib
import csv
import io
import warnings

import numpy as np
import pytest

from bev_mdo.cli import main
from bev_mdo.models import fleet as fl
from bev_mdo.models.cycles import CycleNote


def _notes(path) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CycleNote)
        fl.read_fleet(path)
    return [str(w.message) for w in caught if issubclass(w.category, CycleNote)]


def _scaled(tmp_path, **factors) -> str:
    rows = list(csv.reader(fl.DEFAULT_FLEET.open(newline="", encoding="utf-8")))
    at = {h: i for i, h in enumerate(rows[0])}
    for row in rows[1:]:
        for name, k in factors.items():
            row[at[name]] = f"{float(row[at[name]]) * k:.6g}"
    path = tmp_path / "fleet.csv"
    with path.open("w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows(rows)
    return str(path)


def test_the_shipped_fleet_gives_no_note_and_sets_the_bands():
    assert _notes(None) == []
    f = fl.read_fleet()
    shipped = {"udds_wh_per_km_ac": f.measured["epa_udds"], "hwfet_wh_per_km_ac": f.measured["epa_hwfet"],
               "test_mass_kg": f.test_mass_kg, "road_load_c_n_per_m2_s2": f.road_load_c_n_per_m2_s2,
               "road_load_a_n / (test_mass_kg x g)": f.road_load_a_n / (f.test_mass_kg * fl.G_M_S2)}
    for name, (typical, *_) in fl.PLAUSIBLE_MEDIANS.items():
        assert typical == pytest.approx(float(np.median(shipped[name])), rel=1e-3), name


@pytest.mark.parametrize("factors,column,hint", [
    ({"udds_wh_per_km_ac": 1.609344}, "udds_wh_per_km_ac", "Wh per mile"),
    ({"hwfet_wh_per_km_ac": 0.1}, "hwfet_wh_per_km_ac", "kWh/100 km"),
    ({"road_load_a_n": 1 / 4.448}, "road_load_a_n / (test_mass_kg x g)", "road_load_a_n in lbf"),
    ({"road_load_c_n_per_m2_s2": 1 / 22.26}, "road_load_c_n_per_m2_s2", "lbf/mph^2"),
])
def test_a_column_in_another_unit_is_named(tmp_path, factors, column, hint):
    notes = _notes(_scaled(tmp_path, **factors))
    assert len(notes) == 1 and f"column {column}: fleet median " in notes[0] and hint in notes[0]


def test_masses_in_pounds_name_the_mass_and_the_road_load_per_weight(tmp_path):
    notes = _notes(_scaled(tmp_path, test_mass_kg=2.20462))
    assert len(notes) == 2 and "column test_mass_kg: fleet median 5250" in notes[0] and "pounds" in notes[0]
    assert "test_mass_kg in pounds" in notes[1]


def test_validate_prints_the_note_and_still_runs(tmp_path):
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(["validate", "--data", _scaled(tmp_path, udds_wh_per_km_ac=1.609344), "--energy-model", "chain",
                   "--parameter-set", "epa2022_chain"])
    assert rc == 0 and "note: " in err.getvalue() and "Wh per mile (1.61 x Wh/km)?" in err.getvalue()


def test_one_cars_cycle_energies_far_apart_are_a_note_naming_the_row(tmp_path):
    """One BMW i4 with UDDS 1340 Wh/km (10 x its 162) was scored with no word (max error 88 %, the UDDS pair slope
    0.87 -> 0.21); the fleet's medians stayed plausible. One line names the row; the shipped fleet gives none."""
    rows = list(csv.reader(fl.DEFAULT_FLEET.open(newline="", encoding="utf-8")))
    at = rows[0].index("udds_wh_per_km_ac")
    rows[4][at] = f"{float(rows[4][at]) * 10:.6g}"
    rows[7][at] = f"{float(rows[7][at]) / 10:.6g}"  # (kWh/100 km in one cell)
    path = tmp_path / "fleet.csv"
    with path.open("w", newline="", encoding="utf-8") as f:
        csv.writer(f).writerows(rows)
    said = _notes(path)
    assert len(said) == 2 and all("a typo or one cell's unit?" in n for n in said)
    assert said[0].startswith(f"{path}: row 5 (BMW i4 M50 Gran Coupe (19\" Wheels)): udds_wh_per_km_ac 162")
    assert "is 10.4 x hwfet_wh_per_km_ac 156.5;" in said[0] and ": row 8 (" in said[1]


def test_predictions_off_by_the_wh_per_mile_factor_either_way_are_noted_once_and_kept():
    """fleet.note_energy_unit: a calibrated model 1.609 x off on every car is a note naming the unit, kept in the
    fleet's notes (a set fitted on it keeps them); the thesis constants' 1.38 x and a fleet already noted are not."""
    scored = dict.fromkeys(fl.CYCLES, np.ones(len(fl.read_fleet()), bool))
    for k, said in ((1 / 1.609, "in Wh per mile (1.609 x Wh/km)?"), (1.609, "divided by 1.609"), (1.0, None),
                    (1.38, None), (0.81, None), (1.609 * 1.08, "divided by 1.609"), (1.609 / 1.12, None)):
        f = fl.read_fleet()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", CycleNote)
            fl.note_energy_unit(f, {c: {"energy_wh_per_km": f.measured[c] * k} for c in fl.CYCLES}, scored, "m")
        assert [str(w.message) for w in caught] == f.notes and len(f.notes) == (said is not None), k
        assert said is None or said in f.notes[0]
    f = fl.read_fleet()
    f.energy_unit_noted = True
    fl.note_energy_unit(f, {c: {"energy_wh_per_km": f.measured[c] / 1.609} for c in fl.CYCLES}, scored, "m")
    assert f.notes == []


def test_a_fleet_of_compact_cars_with_masses_in_pounds_is_noted(tmp_path):
    """A Kona trial: a Kona and a Bolt with test masses in lb (4015 and 3862 "kg") were scored at +42 % with no
    word: both masses lie inside the fleet band, and A/(m g) at 0.0037 inside the old x/÷ 2 band (the shipped
    cars span 0.0050-0.0115). The note names the road load per weight."""
    head = ("make,model,test_vehicle_id,config,drive,rated_power_kw,axle_ratio,test_mass_kg,road_load_a_n,"
            "road_load_b_n_per_m_s,road_load_c_n_per_m2_s2,udds_wh_per_km_ac,hwfet_wh_per_km_ac,reported_unit,flag\n")
    path = tmp_path / "lb.csv"
    path.write_text(head + "Hyundai,Kona Electric 64 kWh,KONA1,0,F,150.0,7.981,4015,145.0,1.5,0.413,111.06,135.74,MPGe,\n"
                    "Chevrolet,Bolt EV,BOLT1,0,F,150.0,7.05,3862,140.3,1.5,0.454,114.53,133.28,MPGe,\n", encoding="utf-8")
    notes = [n for n in _notes(path) if "no technology columns" not in n]
    assert len(notes) == 1 and "column road_load_a_n / (test_mass_kg x g): fleet median 0.00" in notes[0]
    assert "test_mass_kg in pounds?" in notes[0]


@pytest.mark.parametrize("factors,named", [
    ({"road_load_a_n": 1 / 4.448, "road_load_b_n_per_m_s": 1 / 9.95, "road_load_c_n_per_m2_s2": 1 / 22.26},
     ["road_load_a_n / (test_mass_kg x g)", "road_load_c_n_per_m2_s2"]),
    ({"test_mass_kg": 2.20462}, ["road_load_a_n / (test_mass_kg x g)"]),
])
def test_one_row_in_other_units_is_a_note_naming_the_row(tmp_path, factors, named):
    """A calibration trial: one Leaf typed in lbf, lbf/mph, lbf/mph^2 was scored -79.9 % on HWFET with no word and
    pushed charger_efficiency to its bound; one in pounds only said CANNOT FOLLOW. The medians stayed plausible."""
    rows = list(csv.reader(fl.DEFAULT_FLEET.open(newline="", encoding="utf-8")))
    f = fl.read_fleet()  # the car of the median road load per weight (one far above it in pounds is not told)
    per_weight = f.road_load_a_n / f.test_mass_kg
    i = int(np.argsort(per_weight)[len(f) // 2]) + 1
    for name, k in factors.items():
        at = rows[0].index(name)
        rows[i][at] = f"{float(rows[i][at]) * k:.6g}"
    path = tmp_path / "fleet.csv"
    with path.open("w", newline="", encoding="utf-8") as out:
        csv.writer(out).writerows(rows)
    notes = _notes(path)
    assert [n.split(": ")[2].split(" ")[0] for n in notes] == [n.split(" ")[0] for n in named], notes
    assert all(n.startswith(f"{path}: row {i + 1} (") and "likely a unit mix-up" in n for n in notes), notes
