"""``bev-mdo sensitivity --method complex`` can never run: the MDA casts every input to float64
(the discipline interface), so it used to evaluate the stencil and then blame the user's model
("complex step not supported by the model: Casting complex values to real ...") even for
disciplines written to be complex-safe. It is now one line before anything runs that says why."""
from __future__ import annotations

from pathlib import Path

from bev_mdo.cli import main

SELLAR = Path(__file__).resolve().parents[2] / "examples" / "sellar" / "sellar_mdf.yaml"


def test_complex_method_is_refused_with_the_reason(capsys):
    code = main(["sensitivity", str(SELLAR), "--order", "1", "--method", "complex"])
    out = capsys.readouterr()
    assert code == 2 and out.out == ""
    assert "float64" in out.err and "--method central" in out.err
    assert "not supported by the model" not in out.err


def test_auto_still_gives_central_sensitivities(capsys):
    code = main(["sensitivity", str(SELLAR), "--order", "1", "--method", "auto", "--json"])
    assert code == 0 and '"method": "central"' in capsys.readouterr().out
