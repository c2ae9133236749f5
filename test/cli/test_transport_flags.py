"""One set of transport flags, with one default, for every command that evaluates designs, and the
same default in the Python API (``Study``): over ROS, through the command's own discipline nodes."""
from __future__ import annotations

import argparse
import inspect
import re

import pytest

from bev_mdo.cli import build_parser, main
from bev_mdo.testing import REPO

EVALUATING = {"optimize", "resume", "evaluate", "sweep", "compare", "sensitivity", "check-totals", "pareto"}
OWN_NODES = {"optimize", "resume", "pareto"}  # bound to their run and recorder: never --attach
# flags a command's run never reads, so its --help must not offer them (every other command's help lists
# exactly the options its parser has; these came with a shared group)
NOT_HONOURED = {"optimize": {"--attach"}, "resume": {"--attach"},
                "pareto": {"--attach", "--initial", "--objective", "--maximize", "--minimize"}}
TRANSPORT_DESTS = ("transport", "attach", "domain_id", "discovery", "static_peers", "discovery_server")
CONFIG = str(REPO / "config" / "leaf_nedc.yaml")


def _required(command: str) -> list[str]:
    """What a command needs besides its options, to parse."""
    return {"resume": ["bag"], "compare": ["c.yaml", "--design", "a=1"]}.get(command, ["c.yaml"])


def _subparsers() -> dict:
    return next(a for a in build_parser()._actions if a.dest == "command").choices


def _transport_options(parser) -> dict:
    """{dest: (option strings, choices, default, nargs, const)} of the parser's transport options."""
    return {a.dest: (tuple(a.option_strings), tuple(a.choices or ()), a.default, a.nargs, a.const)
            for a in parser._actions if a.dest in TRANSPORT_DESTS}


def test_exactly_the_design_evaluating_commands_take_the_transport_flags():
    with_transport = {name for name, p in _subparsers().items() if "transport" in _transport_options(p)}
    assert with_transport == EVALUATING


def test_every_design_evaluating_command_has_the_same_transport_options_and_default():
    subs = _subparsers()
    reference = _transport_options(subs["evaluate"])
    assert set(reference) == set(TRANSPORT_DESTS)
    assert reference["transport"][:3] == (("--transport",), ("ros", "inprocess"), "ros")
    assert reference["attach"][0] == ("--attach",) and reference["attach"][2] is False
    for name in sorted(EVALUATING):
        own = {k: v for k, v in reference.items() if not (name in OWN_NODES and k == "attach")}
        assert _transport_options(subs[name]) == own, name
        args = build_parser([name]).parse_args([name, *_required(name)])
        assert (args.transport, getattr(args, "attach", False)) == ("ros", False), name


@pytest.mark.parametrize("command", sorted(NOT_HONOURED))
def test_help_offers_no_flag_the_command_ignores_or_refuses(command, capsys):
    """optimize, resume and pareto listed --attach and refused it; pareto listed --initial, --objective and
    --maximize/--minimize and ran on its --objectives and a sampled population regardless."""
    with pytest.raises(SystemExit):
        build_parser([command]).parse_args([command, "--help"])
    listed = set(re.findall(r"--[a-z][a-z-]*", capsys.readouterr().out))
    options = {o for a in _subparsers()[command]._actions if a.help != argparse.SUPPRESS for o in a.option_strings}
    assert not (listed | options) & NOT_HONOURED[command]


@pytest.mark.parametrize("command", sorted(EVALUATING))
@pytest.mark.parametrize("old", ["--ros", "--launch"])
def test_the_old_spellings_are_gone(command, old, capsys):
    with pytest.raises(SystemExit) as exc:
        build_parser([command]).parse_args([command, *_required(command), old])
    assert exc.value.code == 2
    assert f"unrecognized arguments: {old}" in capsys.readouterr().err


def test_the_api_has_the_same_default():
    from bev_mdo import Study, Transport
    from bev_mdo.api.optimize import OptimizeOptions

    assert (Transport().transport, Transport().attach) == ("ros", False)
    assert Transport.of(None) == Transport() and OptimizeOptions().transport == "ros"
    runs = ("evaluate", "optimize", "sweep", "sensitivity", "global_sensitivity", "pareto")
    for name in runs:
        default = inspect.signature(getattr(Study, name)).parameters["transport"].default
        assert Transport.of(default) == Transport(), name


@pytest.mark.parametrize("argv, message", [
    (["evaluate", CONFIG, "--transport", "inprocess", "--attach"], "cannot be combined with --transport inprocess"),
    # commands that start their own nodes: argparse's 'unrecognized arguments: --attach (see bev-mdo --help)',
    # which said neither why nor what to give (a user trial); now why, and to drop it, whatever else is wrong
    (["optimize", CONFIG, "--attach", "--no-record"], "optimize: error: optimize --attach: optimize runs its own "
     "discipline nodes, bound to its run and recorder (drop --attach); --attach is for evaluate, sweep"),
    (["optimize", "--attach"], "optimize --attach: optimize runs its own discipline nodes"),  # no config
    (["optimize", CONFIG, "--transport", "inprocess", "--attach"], "(drop --attach)"),
    (["pareto", CONFIG, "--attach"], "pareto: error: pareto --attach: pareto runs its own discipline nodes"),
    (["resume", "--attach"], "resume: error: resume --attach: resume runs its own discipline nodes"),  # no bag
    (["resume", "no_such_bag", "--attach"], "resume --attach: resume runs its own discipline nodes"),
    (["resume", str(REPO / "config"), "--attach", "--output", "x"], "(drop --attach)"),  # a folder with no run
    # ignored without a word over ROS (the run stayed on localhost discovery)
    (["evaluate", CONFIG, "--static-peers", "10.200.0.2"], "--static-peers goes with --discovery static_peers"),
    (["sweep", CONFIG, "--doe", "lhs", "--discovery", "subnet", "--discovery-server", "10.200.0.1:11811"],
     "--discovery-server goes with --discovery server (discovery is 'subnet')"),
])
def test_attach_where_it_cannot_apply_is_one_line_exit_2(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be written, anywhere
    try:
        assert main(argv) == 2
    except SystemExit as exc:  # a flag the command does not have: argparse's exit
        assert exc.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("flags", [["--compose", "none"], ["--instances", "2"], ["--domain-id", "300"],
                                   ["--compose", "all", "--instances", "energy=2"]])
def test_ros_only_optimize_flags_with_inprocess_are_one_line_exit_2(flags, capsys, tmp_path, monkeypatch):
    """They were ignored silently (and --domain-id 300, refused over ROS, accepted)."""
    monkeypatch.chdir(tmp_path)
    assert main(["optimize", CONFIG, "--transport", "inprocess", *flags]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    named = [f for f in flags if f.startswith("--")]
    assert len(err) == 1 and f"{', '.join(named)} cannot be combined with --transport inprocess" in err[0], err
    assert list(tmp_path.iterdir()) == []


def test_ros_only_pareto_flags_with_inprocess_are_one_line_exit_2(capsys, tmp_path, monkeypatch):
    """optimize refused them; pareto ran and ignored --domain-id and --discovery silently."""
    monkeypatch.chdir(tmp_path)
    assert main(["pareto", str(REPO / "config" / "topologies_artemis.yaml"), "--transport", "inprocess", "--domain-id", "300", "--discovery", "localhost",
                 "--generations", "1", "--pop", "4", "--no-plots", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--domain-id, --discovery cannot be combined with --transport inprocess" in err[0], err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv", [["evaluate", CONFIG], ["sweep", CONFIG, "--vary", "motor_kw=60:80:2"],
                                  ["compare", CONFIG, "--design", "motor_kw=70", "--design", "motor_kw=80"],
                                  ["sensitivity", CONFIG, "--order", "1"], ["check-totals", CONFIG]],
                         ids=lambda a: a[0])
def test_ros_only_flags_with_inprocess_are_one_line_exit_2_for_every_evaluating_command(argv, capsys, tmp_path,
                                                                                        monkeypatch):
    """They ran in process and ignored --domain-id silently (optimize and pareto refused it)."""
    monkeypatch.chdir(tmp_path)
    assert main([*argv, "--transport", "inprocess", "--domain-id", "300"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--domain-id cannot be combined with --transport inprocess" in err[0], err


def _layout_options(parser) -> dict:
    return {a.dest: (tuple(a.option_strings), a.default, a.metavar, a.help)
            for a in parser._actions if a.dest in ("instances", "compose")}


def test_resume_lays_its_nodes_out_as_optimize_does(tmp_path, monkeypatch):
    """resume had no --compose ('unrecognized arguments') and always started a process per discipline
    (--compose none: 7 processes, about twice optimize's start-up); its --instances and --compose are
    optimize's, with optimize's default, and reach the run."""
    import bev_mdo.cli.optimize as optimize
    import bev_mdo.cli.resume as resume
    from bev_mdo.config import RunConfig

    subs = _subparsers()
    assert _layout_options(subs["resume"]) == _layout_options(subs["optimize"])
    assert _layout_options(subs["optimize"])["compose"][1] == "coordinator"
    config = RunConfig.load(CONFIG)
    monkeypatch.setattr(resume, "resume_point", lambda *a, **k: (config, {"motor_kw": 80.0}, 3))
    seen = []
    monkeypatch.setattr(optimize, "run_job", lambda cfg, opts, x0=None: seen.append(opts) or 0)
    bag = str(tmp_path / "bag")
    assert main(["resume", bag, "--no-record", "--quiet"]) == 0
    assert main(["resume", bag, "--no-record", "--quiet", "--compose", "none", "--instances", "energy=2"]) == 0
    assert [(o.compose, o.instances) for o in seen] == [("coordinator", None), ("none", "energy=2")]


@pytest.mark.parametrize("command", sorted(EVALUATING - {"pareto"}))
def test_every_command_that_evaluates_designs_takes_no_record(command):
    """evaluate --no-record was 'unrecognized arguments' while optimize, resume and sweep took it: a command that
    never records takes it and does nothing, as asked, without offering it in its help."""
    args = build_parser([command]).parse_args([command, *_required(command), "--no-record"])
    assert args.no_record is True


def test_evaluate_no_record_runs_and_pareto_says_why_it_cannot(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["evaluate", CONFIG, "--set", "motor_kw=80", "--transport", "inprocess", "--no-record"]) == 0
    assert capsys.readouterr().err == "" and list(tmp_path.iterdir()) == []
    with pytest.raises(SystemExit) as exc:
        main(["pareto", CONFIG, "--no-record"])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["bev-mdo pareto: error: pareto --no-record: pareto always records its fronts, one per generation, "
                   "in its bag (OUT/bag); drop --no-record"]
