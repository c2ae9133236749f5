"""What `optimize` prints: rates that mean something per formulation, times that say what they
measure, and the answers; `--bag` works in process."""
from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from bev_mdo.cli import main

CONFIG = str(Path(__file__).resolve().parents[2] / "config/leaf_nedc.yaml")


def _run(*argv):
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["optimize", CONFIG, "--transport", "inprocess", *argv])
    return rc, buf.getvalue()


@pytest.mark.parametrize("formulation,rate", [("mdf", "MDA evals/s"), ("idf", "discipline evals/s")])
def test_progress_rate_fits_the_formulation(formulation, rate):
    rc, out = _run("--formulation", formulation)
    assert rc == 0
    progress = [l for l in out.splitlines() if l.startswith("iter ")]
    assert progress and all(l.endswith(rate) for l in progress)
    assert "optimiser wall time" in out and "(first evaluation to optimum)" in out
    assert "run time" in out and "wall time " not in out.replace("optimiser wall time", "")
    assert "what holds the optimum:" in out and "on its lower bound: battery_kwh" in out


def test_bag_in_process_is_readable_by_history(tmp_path, capsys):
    rc, out = _run("--bag", str(tmp_path / "b"), "--quiet")
    assert rc == 0 and f"bag: {tmp_path / 'b'}" in out
    assert main(["history", str(tmp_path / "b"), "--csv", "-"]) == 0
    csv_text = capsys.readouterr().out
    assert csv_text.startswith("run_id,iteration") and len(csv_text.strip().splitlines()) == 7


def test_an_optimiser_that_did_not_converge_is_said_so_beside_the_table(tmp_path):
    """SLSQP stopped by its iteration limit (or 'Positive directional derivative for linesearch') gave
    success: false in the JSON, but the table, titled 'Optimum', and 'what holds the optimum' said
    nothing: a point short of the optimum read as the optimum (the aerostructure problem, minimised,
    maxiter 3: range 3751.37 against 3733.12)."""
    import yaml

    sellar = Path(__file__).resolve().parents[2] / "examples" / "sellar"
    raw = yaml.safe_load((sellar / "sellar_mdf.yaml").read_text())
    raw["search_path"] = [str(sellar)]
    raw["optimizer"]["options"] = {"maxiter": 2}
    cfg = tmp_path / "sellar_2.yaml"
    cfg.write_text(yaml.safe_dump(raw))
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        main(["optimize", str(cfg), "--transport", "inprocess", "--no-record", "--quiet"])
    out = buf.getvalue()
    assert "warning: SLSQP did not converge: Iteration limit reached" in out
    rc, out = _run("--quiet", "--no-record")
    assert rc == 0 and "did not converge" not in out
