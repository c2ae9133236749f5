"""A run whose vehicle.parameter_set is a file of one's own records which set it was (name, file, SHA-256,
fit date) in its resolved config, and optimize and evaluate name it: the values alone were recorded before,
so nothing said which set a result came from."""
import hashlib
import json

import yaml

from bev_mdo.cli import main
from bev_mdo.config import RunConfig
from bev_mdo.models.params import PARAMETER_SET_DIR
from bev_mdo.testing import REPO


def _config(tmp_path):
    mine = tmp_path / "mine.yaml"
    mine.write_text((PARAMETER_SET_DIR / "epa2022_quasi_static.yaml").read_text()
                    .replace("name: epa2022_quasi_static", "name: mine"))
    text = (REPO / "config" / "leaf_epa_combined.yaml").read_text()
    assert "parameter_set: epa2022_quasi_static" in text
    cfg = tmp_path / "cfg.yaml"
    cfg.write_text(text.replace("parameter_set: epa2022_quasi_static", "parameter_set: mine.yaml"))
    want = {"name": "mine", "file": str(mine.resolve()), "sha256": hashlib.sha256(mine.read_bytes()).hexdigest(),
            "fitted": yaml.safe_load(mine.read_text())["fitted_on"]["date"]}
    return cfg, want


def test_the_resolved_config_records_the_set_and_reads_back(tmp_path):
    cfg, want = _config(tmp_path)
    run = RunConfig.load(cfg)
    assert run.data["vehicle"]["parameter_set_source"] == want and run.parameter_set == want
    again = RunConfig.load(yaml.safe_load(yaml.safe_dump(run.data)))  # a bag's resolved config, read back
    assert again.parameter_set == want and dict(again.vehicle) == dict(run.vehicle)
    assert run.with_vehicle({"load_kg": 80.0}).parameter_set == want  # a node's override keeps the record
    assert RunConfig.load(REPO / "config" / "leaf_epa_combined.yaml").parameter_set == {"name": "epa2022_quasi_static"}


def test_evaluate_and_optimize_name_the_set(tmp_path, capsys):
    cfg, want = _config(tmp_path)
    assert main(["evaluate", str(cfg), "--json", "--transport", "inprocess"]) == 0
    assert json.loads(capsys.readouterr().out)["parameter_set"] == want
    assert main(["optimize", str(cfg), "--transport", "inprocess", "--no-record", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["parameter_set"] == want
    assert main(["optimize", str(cfg), "--transport", "inprocess", "--no-record"]) == 0
    assert (f"parameter set: mine ({want['file']}, sha256 {want['sha256']}, fitted {want['fitted']})"
            in capsys.readouterr().out.splitlines())


def test_a_set_whose_fit_left_notes_says_them_once_when_a_config_loads_it(tmp_path, capsys):
    """A set calibrate wrote with quality.notes (a fleet in other units, a parameter at its bound) was applied by
    a config with no word; a set without notes says nothing."""
    cfg, want = _config(tmp_path)
    assert main(["evaluate", str(cfg), "--json", "--transport", "inprocess"]) == 0
    assert "note:" not in capsys.readouterr().err
    mine = tmp_path / "mine.yaml"
    doc = yaml.safe_load(mine.read_text())
    notes = ["whmi.csv: column udds_wh_per_km_ac: fleet median 258.3 (read as given)",
             "charger_efficiency 0.7 is at its lower bound: the data press it there"]
    doc["quality"]["notes"] = notes
    mine.write_text(yaml.safe_dump(doc, sort_keys=False))
    assert main(["evaluate", str(cfg), "--json", "--transport", "inprocess"]) == 0
    err = capsys.readouterr().err
    for n in notes:
        assert err.count(f"bev-mdo evaluate: note: vehicle.parameter_set {mine}: its fit noted: {n}\n") == 1, err
    assert err.count("note:") == 2
