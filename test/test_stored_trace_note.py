"""A resolved config read again runs the drive-cycle trace its cycle_traces stores (a bag's resume relies on it);
when the CSV of that name on disk holds another trace, or no longer reads as a cycle, one note says so."""
from __future__ import annotations

import copy
import warnings
from pathlib import Path

import pytest
import yaml

from bev_mdo.config import RunConfig
from bev_mdo.models.cycles import DATA_DIR, CycleNote

ROOT = Path(__file__).resolve().parents[1]


def _resolved(tmp_path) -> tuple[Path, dict]:
    csv = tmp_path / "mycycle.csv"
    csv.write_text((DATA_DIR / "epa_udds.csv").read_text())
    raw = yaml.safe_load((ROOT / "config" / "leaf_nedc.yaml").read_text())
    raw["cycle"]["name"] = str(csv)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CycleNote)  # the run that reads the file says nothing of it
        data = yaml.safe_load(yaml.safe_dump(RunConfig.load(raw).data))  # as logs/config.yaml holds it
    return csv, data


def _notes(data: dict) -> tuple[RunConfig, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", CycleNote)
        cfg = RunConfig.load(copy.deepcopy(data))
    return cfg, [str(w.message) for w in caught if issubclass(w.category, CycleNote)]


def test_the_same_file_gives_no_note(tmp_path):
    assert _notes(_resolved(tmp_path)[1])[1] == []


def test_an_edited_file_is_named_and_the_stored_trace_runs(tmp_path):
    csv, data = _resolved(tmp_path)
    stored = copy.deepcopy(data["cycle_traces"][str(csv)])
    rows = csv.read_text().splitlines()
    csv.write_text("\n".join([rows[0]] + [f"{t},{float(v) * 1.2:.4f}" for t, v in (r.split(",") for r in rows[1:])]))
    cfg, notes = _notes(data)
    assert cfg["cycle_traces"][str(csv)] == stored  # the stored trace is the one that runs
    assert len(notes) == 1 and notes[0].startswith(f"{csv}: the file's trace (1369 s, 14.39 km) is not the one "
                                                   "cycle_traces stores for it (1369 s, 11.99 km); the stored trace runs")
    assert "drop its cycle_traces entry" in notes[0]


@pytest.mark.parametrize("text", ["time_s,speed_kmh\n", "not a cycle at all\n"])
def test_a_file_that_no_longer_reads_is_a_note_not_an_error(tmp_path, text):
    csv, data = _resolved(tmp_path)
    csv.write_text(text)
    cfg, notes = _notes(data)
    assert len(notes) == 1 and "the file no longer reads as a cycle (" in notes[0] and str(csv) in notes[0]


def test_a_hand_written_entry_is_checked_against_its_file(tmp_path):
    csv, data = _resolved(tmp_path)
    data["cycle_traces"][str(csv)] = {"time_s": [0, 10, 20], "speed_m_s": [0, 10, 0]}
    notes = _notes(data)[1]
    assert len(notes) == 1 and "cycle_traces stores for it (20 s, 0.1 km)" in notes[0]
