"""The CLI is built from its table of subcommands: only the chosen subcommand's module is imported,
and a subcommand module that fails to import fails loudly (no silent "not built yet")."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from bev_mdo import cli
from bev_mdo.testing import REPO


def _subparsers(parser):
    return next(a for a in parser._actions if a.dest == "command")


def test_every_table_entry_is_registered_by_its_module_with_the_same_help():
    sub = _subparsers(cli.build_parser())  # the full parser: every module imported
    assert list(sub.choices) == list(cli.SUBCOMMANDS)
    helps = {a.dest: a.help for a in sub._choices_actions}
    for command, (_, help_text) in cli.SUBCOMMANDS.items():
        assert helps[command] == help_text, command


def test_a_lazy_parser_lists_every_subcommand_in_table_order():
    for argv in ([], ["--help"], ["validate"], ["compare", "x"], ["sweep"]):
        sub = _subparsers(cli.build_parser(argv))
        assert list(sub.choices) == list(cli.SUBCOMMANDS)
        assert [a.dest for a in sub._choices_actions] == list(cli.SUBCOMMANDS)


def test_the_chosen_subcommand_gets_its_full_parser():
    args = cli.build_parser(["validate", "--json"]).parse_args(["validate", "--json"])
    assert args.json is True and args.energy_model == "quasi_static"
    with pytest.raises(SystemExit):  # a placeholder would accept nothing; the real parser refuses the typo
        cli.build_parser(["validate", "--jsn"]).parse_args(["validate", "--jsn"])


def _imported_after(code: str) -> dict:
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, timeout=60,
                       env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"})
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(p.stdout.strip().splitlines()[-1])


def test_only_the_chosen_module_and_no_heavy_library_is_imported():
    seen = _imported_after(
        "import json, sys\n"
        "from bev_mdo.cli import build_parser\n"
        "build_parser(['validate']).parse_args(['validate'])\n"
        "print(json.dumps(sorted(m for m in sys.modules if m.startswith(('bev_mdo.cli.', 'rclpy', 'scipy', "
        "'matplotlib')))))\n")
    assert seen == ["bev_mdo.cli.validate"]


def test_validate_runs_without_rclpy_scipy_or_matplotlib(tmp_path):
    """Nor numba: the default quasi_static model runs its numpy passes for the one fleet batch."""
    seen = _imported_after(
        "import contextlib, io, json, sys\n"
        "from bev_mdo.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        "    code = main(['validate'])\n"
        "assert code == 0\n"
        "print(json.dumps(sorted({m.split('.')[0] for m in sys.modules} & {'rclpy', 'scipy', 'matplotlib', "
        "'numba'})))\n")
    assert seen == []


def test_a_subcommand_module_that_fails_to_import_fails_loudly(monkeypatch):
    monkeypatch.setitem(sys.modules, "bev_mdo.cli.status", None)  # as if status.py were broken
    with pytest.raises(ModuleNotFoundError, match="bev_mdo.cli.status"):
        cli.build_parser()
    with pytest.raises(ModuleNotFoundError, match="bev_mdo.cli.status"):
        cli.main(["status"])
    # other subcommands are not affected by it
    assert cli.build_parser(["graph"]).parse_args(["graph", "c.yaml"]).config == "c.yaml"


@pytest.mark.parametrize("argv", [["optimize", "c.yaml", "--domain-id", "abc"], ["optimize", "c.yaml", "--formulation", "xyz"],
                                  ["optimize"], ["nosuch"]])
def test_a_usage_mistake_is_one_line_naming_help(argv, capsys):
    """argparse printed the whole usage (14 lines for optimize) where every other mistake is one line."""
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1 and "error: " in err and "--help)" in err, err


def test_a_history_header_cut_to_its_width_says_so():
    """A user output top_speed_kmh was headed 'top_speed_km' over 'km/h': a whole name with its unit, read wrong."""
    from bev_mdo.cli.history import _header

    assert _header("constraint.top_speed_kmh", {"top_speed_kmh": "km/h"}) == ("top_speed_k…", "km/h")
    assert _header("evaluations.motor_speed", {}) == ("motor_spe…", "evals")
    assert _header("constraint.range_km", {"range_km": "km"}) == ("range", "km")
    assert _header("design.x_short", {}) == ("x_short", "")


def test_a_config_taken_by_set_is_named_as_the_cause(capsys):
    """`evaluate --set motor_kw=90 CONFIG` said only 'the following arguments are required: config'."""
    with pytest.raises(SystemExit) as exc:
        cli.main(["evaluate", "--set", "motor_kw=90", "config/leaf_nedc.yaml"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err.count("\n") == 1, err
    assert "required: config (--set takes every word after it: put CONFIG before it)" in err, err
    # no option of several values given, or none that took a word that is no value of its: no such words (reviews)
    for argv in (["history"], ["evaluate"], ["evaluate", "--set", "motor_kw=90"]):
        with pytest.raises(SystemExit):
            cli.main(argv)
        assert "takes every word" not in capsys.readouterr().err


def test_an_unknown_option_is_said_by_its_subcommand(capsys):
    """`sweep ... --compose none` said 'bev-mdo: error: unrecognized arguments' and pointed at the top help."""
    with pytest.raises(SystemExit) as exc:
        cli.main(["sweep", "config/leaf_nedc.yaml", "--compose", "none"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and err == ("bev-mdo sweep: error: unrecognized arguments: --compose none "
                                           "(see bev-mdo sweep --help)\n"), err
    with pytest.raises(SystemExit):  # given before the subcommand: the top parser's (the review)
        cli.main(["--bogus", "sweep", "config/leaf_nedc.yaml"])
    assert capsys.readouterr().err.startswith("bev-mdo: error: unrecognized arguments: --bogus")
    with pytest.raises(SystemExit):  # a subcommand's action names itself: `bag info`, not `bag`
        cli.main(["bag", "info", "bags/none", "--bogus"])
    assert capsys.readouterr().err == ("bev-mdo bag info: error: unrecognized arguments: --bogus "
                                       "(see bev-mdo bag info --help)\n")
    with pytest.raises(SystemExit):  # given to `bag`, before its action: bag's (the review)
        cli.main(["bag", "--bogus", "info", "bags/none"])
    assert capsys.readouterr().err.startswith("bev-mdo bag: error: unrecognized arguments: --bogus (see bev-mdo bag --help)")
