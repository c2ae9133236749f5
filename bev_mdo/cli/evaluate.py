"""``bev-mdo evaluate CONFIG --set motor_kw=80 gear_ratio=8 battery_kwh=24 [--json] [--transport ros|inprocess] [--attach]``.

Evaluates one design through every discipline (one multidisciplinary analysis)
and prints each output, the objective, every constraint with its margin, and
feasibility. Design variables not given take their ``initial`` value.
"""
from __future__ import annotations

import sys

from bev_mdo import jsontext


def register(subparsers) -> None:
    p = subparsers.add_parser("evaluate", description=__doc__.splitlines()[0])
    p.add_argument("config", help="run config YAML, e.g. config/leaf_nedc.yaml")
    p.add_argument("--set", dest="assignments", nargs="+", action="extend", default=[], metavar="NAME=VALUE",
                   help="design values (or model-parameter overrides); also comma-separated a=1,b=2")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    from bev_mdo.cli.flags import add_override_arguments, add_transport_arguments

    add_transport_arguments(p)
    add_override_arguments(p)
    p.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.api import evaluate
    from bev_mdo.api.transport import Transport
    from bev_mdo.cli import flags

    config = flags.load_config(args)
    report = evaluate.design(config, flags.parse_assignments(args.assignments), Transport.of(args))
    if args.json:
        print(jsontext.dumps(report))
    else:
        if line := cycles_line(config.data):
            print(line)
        from bev_mdo.config.sections import cycle_names

        print_table(report, epa=any(str(n).startswith("epa_") for n in cycle_names(config.data))
                    if isinstance(config.data.get("cycle"), dict) else False)
    return 0 if report["ok"] else 1


def cycles_line(cfg) -> str:
    """The drive cycles the run names, each with its duration, distance and top speed (a trace in m/s under a
    km/h header shows as a 14 km/h top speed), or '' for a problem without a cycle."""
    from bev_mdo.config.sections import cycle_names
    from bev_mdo.models.cycles import load_cycle

    if not isinstance(cfg.get("cycle"), dict):
        return ""
    # the discipline entry each cycle's key names (disciplines[1].options.cycle_weights), None for cycle.name
    entries = {name: None if key == "cycle.name" else cfg["disciplines"][int(key.split("[")[1].split("]")[0])]
               for name, key in cycle_names(cfg).items()}
    own = {e["name"] for e in entries.values() if e is not None}
    said = []
    for name, entry in entries.items():  # where the config names it says what it is for
        c = load_cycle(name, cfg.get("cycle_traces"))
        use = f"cycle.name: not the {' or '.join(sorted(own))} discipline's" if own else ""
        if entry is not None:
            weights = entry["options"].get("cycle_weights") or {}
            use = (f"{entry['name']}: {weights[name]:g} of the distance" if name in weights else f"{entry['name']}'s")
        said.append(f"{c.name} {c.duration_s:.0f} s, {c.distance_m / 1e3:.2f} km, top {c.max_speed_kmh:.1f} km/h"
                    + (f" ({use})" if use else ""))
    return f"cycle{'s' if len(said) > 1 else ''}: " + "; ".join(said)


BASIS = {"energy_wh_per_km": "from the battery", "energy_wall_wh_per_km": "from the wall",
         "range_km": "unadjusted"}  # on an EPA cycle also: an EPA label's ~0.7x (docs/validation.md: the range)


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.6g}"


def print_table(report: dict, epa: bool = False) -> None:
    """Readable tables of design, outputs and constraints."""
    from rich.console import Console
    from rich.table import Table

    from bev_mdo.mdo.units import unit_of

    units = report.get("units", {})
    console = Console(file=sys.stdout, width=100)
    t = Table(title="design and outputs", show_header=True)
    for col in ("variable", "value", "unit", "role"):
        t.add_column(col, justify="right" if col == "value" else "left")
    for k, v in report["design"].items():
        t.add_row(k, _fmt(v), unit_of(k, units), "design")
    for k, v in report.get("parameters", {}).items():
        t.add_row(k, _fmt(v), unit_of(k, units), "parameter")
    obj = report["objective"]["name"]
    role = "objective (max)" if report["objective"].get("maximize") else "objective (min)"
    for k, v in report["outputs"].items():
        what = role if k == obj else "output"
        basis = BASIS.get(k, "") + (": an EPA label's ~0.7x" if epa and k == "range_km" else "")
        t.add_row(k, _fmt(v), unit_of(k, units), f"{what}, {basis}" if basis else what)
    console.print(t)
    c = Table(title="constraints", show_header=True)
    for col in ("constraint", "value", "lower", "upper", "margin", "unit", "ok"):
        c.add_column(col, justify="left" if col in ("constraint", "unit") else "right")
    for k, r in report["constraints"].items():
        c.add_row(k, _fmt(r["value"]), _fmt(r["lower"]), _fmt(r["upper"]), _fmt(r["margin"]), unit_of(k, units),
                  "yes" if r["satisfied"] else "[bold red]NO[/]")
    console.print(c)
    if not report["ok"]:
        from rich.markup import escape

        console.print(f"[bold red]evaluation failed:[/] {escape(report['error'])}", soft_wrap=True)  # one line, unwrapped
    for note in report.get("notes", ()):
        console.print(f"note: {note}", markup=False)
    unit = unit_of(obj, units)
    console.print(f"objective {obj} = {_fmt(report['objective']['value'])}{'' if unit == '–' else ' ' + unit}; "
                  f"feasible: {'yes' if report['feasible'] else 'NO'}")
