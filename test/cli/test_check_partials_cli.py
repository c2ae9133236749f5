"""bev-mdo check-partials says what it checked."""
from pathlib import Path

from bev_mdo.cli import main

LEAF = Path(__file__).resolve().parents[2] / "config" / "leaf_nedc.yaml"


def test_nothing_to_check_is_not_called_agreement(capsys):
    """The acceleration discipline has no analytic partials: the check printed 'all analytic partials agree
    with finite differences' although it compared nothing."""
    assert main(["check-partials", str(LEAF), "--discipline", "acceleration"]) == 0
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("nothing checked: no discipline checked here declares analytic partials")
    assert main(["check-partials", str(LEAF), "--discipline", "range"]) == 0  # eq 7-28's partials
    assert capsys.readouterr().out.strip().splitlines()[-1] == "all analytic partials agree with finite differences"


def test_check_totals_does_not_call_noise_about_zero_its_largest_relative_error():
    """A total of 0 against finite differences of 8e-11 (both within atol) was the 'largest relative error 1'."""
    from bev_mdo.cli.check_totals import summary

    row = lambda of, a, b: {"of": of, "wrt": "x", "total": a, "fd": b, "abs_error": abs(a - b),
                            "rel_error": abs(a - b) / max(abs(a), abs(b)) if max(abs(a), abs(b)) else 0.0}
    rep = {"atol": 1e-6, "ok": True, "rows": [row("g", 0.0, 8e-11), row("f", 2.0, 2.000004)]}
    assert summary(rep).startswith("largest relative error 2e-06 (d f / d x) among the differences above atol 1e-06")
    rep["rows"] = rep["rows"][:1]
    assert summary(rep) == "every difference is within atol 1e-06; all totals agree with finite differences"


def test_a_point_outside_the_bounds_is_noted_as_evaluate_notes_it(capsys):
    """`check-totals --at battery_kwh=200` (bounds 20-40 here) ran and exited 0 without a word, where evaluate
    says such a point is outside its bounds and evaluated as given: now the same one stderr note, both checks."""
    import json

    from bev_mdo.testing import REPO

    sellar = REPO / "examples" / "sellar" / "sellar_mdf.yaml"
    for cmd, extra in (("check-totals", ["--transport", "inprocess"]), ("check-partials", [])):
        assert main([cmd, str(sellar), "--at", "x=12", "--json", *extra]) == 0
        out = capsys.readouterr()
        assert json.loads(out.out)["ok"] is True
        assert out.err.strip().splitlines() == [f"bev-mdo {cmd}: note: x = 12 is outside its bounds [0, 10] "
                                                "(evaluated as given)"]
        assert main([cmd, str(sellar), "--at", "x=10", "--json", *extra]) == 0  # on a bound: nothing to say
        assert capsys.readouterr().err == ""


def test_a_tolerance_out_of_range_is_named_with_its_value(capsys):
    """`--step 0` said '--step must be in (0, 0.1), --rtol and --atol >= 0': which one, and at what value?"""
    for cmd, extra in (("check-totals", ["--transport", "inprocess"]), ("check-partials", [])):
        for flag, value, said in (("--step", "0", "--step 0: must be in (0, 0.1)"),
                                  ("--rtol", "-1e-3", "--rtol -0.001: must be >= 0, finite"),
                                  ("--atol", "nan", "--atol nan: must be >= 0, finite"),
                                  ("--rtol", "1e400", "--rtol inf: must be >= 0, finite")):  # every check passed
            assert main([cmd, str(LEAF), f"{flag}={value}", *extra]) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert err == [f"bev-mdo {cmd}: error: {said}"]
