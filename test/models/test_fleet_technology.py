"""The technology columns of the shipped fleet file: every value has a source or is 'unknown'."""
import csv

import numpy as np
import pytest

from bev_mdo.models import fleet as fl


def _rows():
    with open(fl.DEFAULT_FLEET, newline="") as f:
        return list(csv.DictReader(f))


def _sources():
    with open(fl.TECHNOLOGY_SOURCES, newline="") as f:
        return list(csv.DictReader(f))


def test_every_technology_value_has_a_source_or_is_unknown():
    rows, sources = _rows(), _sources()
    by_key = {(s["test_vehicle_id"], s["config"], s["column"]): s for s in sources}
    assert len(by_key) == len(sources), "one source line per (vehicle, column)"
    for i, r in enumerate(rows, start=2):
        for col, allowed in fl.TECHNOLOGY.items():
            value = r[col]
            assert value in allowed, f"row {i}, {col}: {value!r}"
            src = by_key.get((r["test_vehicle_id"], r["config"], col))
            if value == "unknown":
                assert src is None, f"row {i}, {col}: unknown but a source is listed"
                continue
            assert src is not None, f"row {i}, {col}: {value!r} has no source"
            assert int(src["row"]) == i and src["value"] == value, f"row {i}, {col}: source line disagrees"
            assert len(src["source"].strip()) > 20, f"row {i}, {col}: source too short to find: {src['source']!r}"
    # no source line for a vehicle or column that is not in the file
    keys = {(r["test_vehicle_id"], r["config"]) for r in rows}
    assert all((s["test_vehicle_id"], s["config"]) in keys and s["column"] in fl.TECHNOLOGY for s in sources)


def test_driven_axles_follow_the_epa_drive_column_and_motors_their_axles():
    f = fl.read_fleet()
    drive_awd = np.array([d in ("A", "4", "P") for d in f.drive])
    assert np.array_equal(f.driven_axles, np.where(drive_awd, 2.0, 1.0))
    tech = f.technology
    for i, pos in enumerate(tech["driven_axle_position"]):
        assert (tech["motor_front"][i] == "none") == (pos == "rear")
        assert (tech["motor_rear"][i] == "none") == (pos == "front")


def test_the_data_readme_states_the_provenance_of_the_technology_columns():
    text = (fl.DATA_DIR / "README.md").read_text()
    for col in fl.TECHNOLOGY:
        assert col in text
    assert "technology_sources.csv" in text and "unknown" in text


@pytest.mark.parametrize("col, value, expect", [
    ("motor_rear", "PMSM-ish", "column motor_rear: 'PMSM-ish' is not one of"),
    ("driven_axles", "1", "column driven_axles: 1 contradicts drive 'A'"),
])
def test_a_bad_technology_value_is_one_line(tmp_path, col, value, expect):
    rows = _rows()
    awd = next(r for r in rows if r["drive"] == "A")
    awd[col] = value
    p = tmp_path / "fleet.csv"
    with open(p, "w", newline="") as f:
        w = csv.DictWriter(f, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    with pytest.raises(ValueError, match=expect):
        fl.read_fleet(p)
