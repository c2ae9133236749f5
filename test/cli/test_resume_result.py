"""`report` and `resume` of a finished run stand on its result, not its last record: with --starts the
last record is whichever start finished last. Sellar with 8 starts printed obj 3.18339 at z1 1.97764,
while report's 'Final iterate' showed 4.13076 at z1 -1.717 (another start's local optimum) and resume
restarted there and ended at 4.13076."""
from __future__ import annotations

from pathlib import Path

import pytest

from bev_mdo.cli import main

SELLAR = Path(__file__).resolve().parents[2] / "examples" / "sellar" / "sellar_mdf.yaml"


def test_a_multistart_run_is_reported_and_resumed_at_its_result(tmp_path, capsys):
    from bev_mdo.bag.history import history

    bag = tmp_path / "ms"
    assert main(["optimize", str(SELLAR), "--transport", "inprocess", "--starts", "8", "--bag", str(bag),
                 "--json", "--quiet"]) == 0
    import json

    result = json.loads(capsys.readouterr().out)
    rows = history(bag)
    assert rows[-1]["design"] != result["design"]  # the last record is another start's
    assert main(["report", str(bag)]) == 0
    md = (bag / "report.md").read_text()
    k = next(r["iteration"] for r in reversed(rows) if r["design"] == result["design"] and r["feasible"])
    assert f"## The run's result (iteration {k})" in md and "## Final iterate" not in md
    assert f"| obj | – | {result['objective']:.6g} |" in md
    capsys.readouterr()
    assert main(["resume", str(bag), "--transport", "inprocess", "--output", str(tmp_path / "r"), "--quiet"]) == 0
    assert f"resuming sellar_mdf from the run's result (iteration {k}, not its last record)" in capsys.readouterr().out
    assert history(tmp_path / "r")[0]["design"] == pytest.approx(result["design"])
