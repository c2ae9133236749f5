"""``bev-mdo evaluate CONFIG --set motor_kw=80 gear_ratio=8 battery_kwh=24 [--json] [--ros]``.

Evaluates one design through every discipline (one multidisciplinary analysis)
and prints each output, the objective, every constraint with its margin, and
feasibility. Design variables not given take their ``initial`` value.
"""
from __future__ import annotations

import json
import sys

from bev_mdo.cli import UsageError


def register(subparsers) -> None:
    p = subparsers.add_parser("evaluate", help="evaluate one design through all disciplines",
                              description=__doc__.splitlines()[0])
    p.add_argument("config", help="run config YAML, e.g. config/leaf_nedc.yaml")
    p.add_argument("--set", dest="assignments", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                   help="design values (or model-parameter overrides); also comma-separated a=1,b=2")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    from bev_mdo.cli.overrides import add_override_arguments
    from bev_mdo.cli.ros_args import add_transport_arguments

    add_transport_arguments(p)
    add_override_arguments(p)
    p.set_defaults(func=run)


def ros_session(config, args, node_name: str = "bev_mdo_client"):
    """The ROS session (sessions.EvaluateRosSession) of ``evaluate``/``sensitivity``/``sweep`` over ROS,
    with the command line's ros flags; UsageError when the ROS transport is not installed."""
    import importlib

    try:  # the ROS libraries only: a bev_mdo module that fails to import raises as it is
        for lib in ("rclpy", "bev_mdo_msgs.msg"):
            importlib.import_module(lib)
    except ModuleNotFoundError:
        raise UsageError("--ros needs the ROS transport (rclpy and bev_mdo_msgs)") from None
    from bev_mdo.cli.ros_args import ros_section
    from bev_mdo.sessions import EvaluateRosSession

    return EvaluateRosSession(config, ros_section(config, args), launch=bool(getattr(args, "launch", False)),
                              node_name=node_name)


def close_ros(session, ok: bool = True) -> None:
    """End a ROS session; print its notes (drops, unsigned results) on stderr if the command ended well."""
    for line in session.close(ok):
        print(f"bev-mdo: {line}", file=sys.stderr)


def parse_assignments(items: list[str]) -> dict[str, float]:
    """``["a=1,b=2", "c=3"]`` -> {a: 1.0, b: 2.0, c: 3.0}; UsageError on a malformed item."""
    out: dict[str, float] = {}
    for item in items:
        for part in filter(None, (s.strip() for s in item.split(","))):
            name, sep, value = part.partition("=")
            if not sep or not name.strip():
                raise UsageError(f"--set {part!r} must be NAME=VALUE, e.g. motor_kw=80")
            try:
                out[name.strip()] = float(value)
            except ValueError:
                raise UsageError(f"--set {name.strip()}={value!r}: value must be a number") from None
    return out


def _evaluator(config, use_ros: bool, args=None):
    if use_ros:
        return ros_session(config, args)
    from bev_mdo.config import resolve_disciplines
    from bev_mdo.mdo.evaluator import InProcessEvaluator

    return InProcessEvaluator(resolve_disciplines(config))


def run(args) -> int:
    from bev_mdo.cli import overrides
    from bev_mdo.cli.ros_args import uses_ros
    from bev_mdo.config import run_settings
    from bev_mdo.mdo.driver import evaluate_design
    from bev_mdo.mdo.problem import Problem

    config = overrides.load(args)
    given = parse_assignments(args.assignments)
    problem = Problem.from_config(config["problem"])
    design = {**{d.name: d.initial for d in problem.design_variables}, **given}
    for d in problem.design_variables:  # evaluated as given, but a user should know it is off the design space
        v = given.get(d.name)
        if isinstance(v, (int, float)) and not d.lower <= v <= d.upper:
            print(f"bev-mdo evaluate: note: {d.name} = {v:g} is outside its bounds [{d.lower:g}, {d.upper:g}] "
                  "(evaluated as given)", file=sys.stderr)
    use_ros = uses_ros(args)
    session = _evaluator(config, use_ros, args)
    evaluator = session.evaluator if use_ros else session
    ok = False
    try:
        report = evaluate_design(run_settings(config), evaluator, design)
        ok = True
    finally:
        if use_ros:
            close_ros(session, ok)
        else:
            session.close()
    if args.json:
        print(json.dumps(report, indent=2, allow_nan=True))
    else:
        print_table(report)
    return 0 if report["ok"] else 1


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.6g}"


def print_table(report: dict, file=None) -> None:
    """Readable tables of design, outputs and constraints (rich when available)."""
    from rich.console import Console
    from rich.table import Table

    console = Console(file=file or sys.stdout, width=100)
    t = Table(title="design and outputs", show_header=True)
    t.add_column("variable")
    t.add_column("value", justify="right")
    t.add_column("role")
    for k, v in report["design"].items():
        t.add_row(k, _fmt(v), "design")
    obj = report["objective"]["name"]
    role = "objective (max)" if report["objective"].get("maximize") else "objective (min)"
    for k, v in report["outputs"].items():
        t.add_row(k, _fmt(v), role if k == obj else "output")
    console.print(t)
    c = Table(title="constraints", show_header=True)
    for col in ("constraint", "value", "lower", "upper", "margin", "ok"):
        c.add_column(col, justify="left" if col == "constraint" else "right")
    for k, r in report["constraints"].items():
        c.add_row(k, _fmt(r["value"]), _fmt(r["lower"]), _fmt(r["upper"]), _fmt(r["margin"]),
                  "yes" if r["satisfied"] else "[bold red]NO[/]")
    console.print(c)
    if not report["ok"]:
        console.print(f"[bold red]evaluation failed:[/] {report['error']}")
    console.print(f"objective {obj} = {_fmt(report['objective']['value'])}; "
                  f"feasible: {'yes' if report['feasible'] else 'NO'}")
