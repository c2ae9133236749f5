"""``bev-mdo history BAG [--csv FILE]``: the optimisation history of a recorded run.

The table fits the terminal: columns are chosen by priority (iteration, objective, violation,
feasibility, status: ok or failed, design variables, constraints, evaluation counts) and their headers abbreviated
(quantity over unit); the caption names what did not fit. ``--csv`` has every column.
A bag without iteration records says so (and what it holds instead) on stderr and exits 1; an ``optimize`` bag
whose run did not finish (no end-of-run record: a signal or an error stopped it) says so on stderr, as ``report``.
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from bev_mdo.cli import is_stdout, write_text_file
from bev_mdo.cli.flags import add_bag_argument

# fixed headers (quantity, unit) of the record's own columns
_FIXED = {
    "iteration": ("iter", ""), "objective": ("objective", ""), "max_violation": ("max", "violation"),
    "feasible": ("feasible", ""), "status": ("status", ""), "mda_evaluations": ("MDA", "evals"), "formulation": ("form.", ""),
    "optimizer": ("optimizer", ""),
}
# short quantity names of built-in variables (their units come from the disciplines' declarations)
_SHORT = {
    "energy_wh_per_km": "energy", "energy_wall_wh_per_km": "wall energy", "range_km": "range",
    "accel_time_0_100_s": "0-100", "motor_speed_max_rad_s": "ω max", "powertrain_cost_usd": "cost",
    "vehicle_mass_kg": "mass", "motor_kw": "motor", "motor_rear_kw": "motor rear", "gear_ratio": "gear",
    "gear_ratio_rear": "gear rear", "battery_kwh": "battery",
}
EXIT_NO_ITERATIONS = 1


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "history", description="The IterationRecords of a bag as a table fitted to the terminal width (every column "
                    "with --csv). Exit status 1 if the bag holds no iteration records (a pareto bag "
                    "holds fronts instead: the CSV files beside it).")
    add_bag_argument(parser)
    parser.add_argument("--csv", metavar="FILE", help="write the history as CSV ('-' or /dev/stdout for stdout)")
    parser.add_argument("--run-id", help="this run (default: the bag's own run; needed for a recording of "
                                         "several runs)")
    add_verify_arguments(parser)
    parser.add_argument("--width", type=int, default=None,
                        help="table width in characters (default: the terminal's; all columns when piped)")
    parser.set_defaults(func=run)


def add_verify_arguments(parser) -> None:
    """--key-file and --no-verify, for every command that reads a run's iteration records."""
    parser.add_argument("--key-file", default=None,
                        help="key that signed the run (default: the run's key beside the bag, "
                             "<bag's parent>/.keys/<bag name>/sign.key; a key path stored in the bag is not trusted)")
    parser.add_argument("--no-verify", action="store_true",
                        help="read the records without checking their signatures or the bag's signing record "
                             "(the output says that verification is off)")


def no_iterations(args, bag, checks: dict) -> str:
    """The line of a bag (or its run ``args.run_id``) without iteration records: what it holds instead."""
    from bev_mdo.bag.history import runs_held

    what = f" of run {args.run_id}" if args.run_id else ""
    held = runs_held(checks["other_run_ids"]) if checks.get("other_run_ids") else describe_other_content(bag)
    return f"{args.bag}: no iteration records{what}; {held}"


def describe_other_content(bag) -> str:
    """What a bag without iteration records holds, in one sentence."""
    from bev_mdo.bag.history import ITERATION_TYPE

    pareto = [t for t, ty in bag.topics.items() if ty.endswith("/ParetoFront")]
    if pareto:
        from bev_mdo.studies.topologies import read_fronts

        fronts = read_fronts(bag.bag_dir if bag.bag_dir else bag.mcap_path)
        tops = sorted({f["topology"] for f in fronts if f["topology"]})
        gens = max((f["generation"] for f in fronts), default=0)
        where = (f"{len(tops)} topolog{'y' if len(tops) == 1 else 'ies'}: {', '.join(tops)}; " if tops else "")
        files = ("pareto_<topology>.csv files" if tops else "front.csv") + " beside the bag (when the run finished)"
        return (f"it is a Pareto bag: {len(fronts)} ParetoFront messages on {', '.join(pareto)} "
                f"({where}up to generation {gens}); the final fronts are in the {files}, every generation's "
                "in the bag (not shown by bev-mdo report)")
    if not bag.message_count:  # its topics may be declared (the recorder's), with nothing recorded on them
        return "it holds no messages at all"
    kinds = sorted({ty for ty in bag.topics.values() if ty != ITERATION_TYPE})
    if not kinds:  # every message an iteration record of the run, none kept (the check note says why)
        return f"its {bag.message_count} messages are iteration records, none of them kept"
    return f"it holds {bag.message_count} messages of {', '.join(kinds)}"


def run(args) -> int:
    from bev_mdo.bag.history import (by_optimize, check_note, flat_rows, read_answers, records_phrase, run_ending,
                                     runs_held, to_csv, verified_history)
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.bag.report import bag_units

    if args.width is not None and args.width < 40:  # narrower than any table: a blank line and exit 0 before
        raise ValueError(f"--width {args.width}: the table needs at least 40 characters")
    bag = open_bag(args.bag)
    if bag.truncated:
        print(bag.recovery_note(), file=sys.stderr)
    if bag.metadata_note:
        print(bag.metadata_note, file=sys.stderr)
    checks: dict = {}
    rows, signer = verified_history(bag, run_id=args.run_id, key_file=args.key_file, checks=checks,
                                    no_verify=args.no_verify)
    if check_note(checks):
        print(f"{args.bag}: {check_note(checks)}", file=sys.stderr)
    # the bag's own run, written by `optimize`, with no end-of-run record: as report's first line, the run did not
    # finish and its last record is not a result; one left out (not signed with the run's key): how it ended is not known
    told: dict = {}
    if rows and args.run_id in (None, bag.info.get("run_id")) and read_answers(bag, signer, told) is None \
            and (told or by_optimize(bag)):
        ending = run_ending(bag, rows, None, told, then=f"iteration {rows[-1]['iteration']} is")
        if ending:  # (None: a sweep's)
            print(f"{args.bag}: {ending[1].replace('**', '')}", file=sys.stderr)
    if not rows:
        print(f"bev-mdo history: {no_iterations(args, bag, checks)}", file=sys.stderr)
        return EXIT_NO_ITERATIONS
    if args.csv:
        target = Path(args.csv).resolve()
        if not is_stdout(args.csv) and target.parent == bag.bag_dir.resolve() and (
                target.suffix == ".mcap" or target.name == "metadata.yaml"):
            # it replaced the .mcap or metadata.yaml it had just read, and the bag was lost
            raise ValueError(f"--csv {args.csv}: that is the bag's own {target.name}; write the CSV elsewhere")
        text = to_csv(rows)
        if is_stdout(args.csv):
            sys.stdout.write(text)
        else:
            write_text_file(args.csv, text)
            print(f"wrote {records_phrase(rows)} to {args.csv}")
        return 0
    width = args.width
    if width is None and (sys.stdout.isatty() or os.environ.get("COLUMNS")):
        width = shutil.get_terminal_size((120, 24)).columns
    print_table(flat_rows(rows), width=width, units=bag_units(bag))
    return 0


def _header(col: str, units: dict | None = None) -> tuple[str, str]:
    """(quantity, unit) of a column; the unit as the run's disciplines declare it."""
    if col in _FIXED:
        return _FIXED[col]
    name = col.split(".", 1)[1] if "." in col else col
    if col.startswith("evaluations."):
        return _cut(name, 10), "evals"
    from bev_mdo.mdo.units import unit_of

    return _cut(_SHORT.get(name, name), 12), unit_of(name, units or {})


def _cut(name: str, width: int) -> str:
    """``name`` in ``width`` characters, a cut one ending in '…' ('top_speed_km' over 'km/h' read as a
    name with its unit, cut from top_speed_kmh)."""
    return name if len(name) <= width else name[:width - 1] + "…"


def _priority(col: str) -> int:
    order = ("iteration", "start", "objective", "max_violation", "feasible", "status", "design.", "constraint.",
             "mda_evaluations", "evaluations.", "formulation", "optimizer")
    for i, p in enumerate(order):
        if col == p or (p.endswith(".") and col.startswith(p)):
            return i
    return len(order)


def choose_columns(rows: list[dict], width: int | None, units: dict | None = None) -> tuple[list, list, dict, int]:
    """(columns shown in table order, columns left out, {column: cells}, the width they take) for a
    width (None: every column)."""
    skip = {"run_id", "sequence", "objective_name", "wall_time_s"}
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns and k not in skip]
    # constant text columns go into the title instead
    columns = [c for c in columns if not (c in ("formulation", "optimizer", "starts", "seed")
                                          and len({str(r.get(c)) for r in rows}) == 1)]
    if width is not None and all(r.get("status") == "ok" for r in rows):  # the table shows it where one failed
        columns = [c for c in columns if c != "status"]
    cells = {c: [_fmt(r.get(c, "")) for r in rows] for c in columns}
    need = {}
    for c in columns:
        q, u = _header(c, units)
        need[c] = max([len(q), len(u)] + [len(v) for v in cells[c]]) + 3
    chosen, used = [], 1
    for c in sorted(columns, key=lambda c: (_priority(c), columns.index(c))):
        if width is None or used + need[c] <= width:
            chosen.append(c)
            used += need[c]
    shown = [c for c in columns if c in chosen]
    return shown, [c for c in columns if c not in chosen], cells, used


def print_table(rows: list[dict], width: int | None = None, file=None, units: dict | None = None) -> None:
    """The history as a table; ``units``: {variable: unit} as the run's disciplines declare them."""
    from rich.console import Console
    from rich.table import Table

    from bev_mdo.bag.history import records_phrase

    out = file or sys.stdout
    shown, left, cells, used = choose_columns(rows, width, units)
    first = rows[0]
    title = records_phrase(rows)
    for k in ("formulation", "optimizer"):
        if k not in shown and first.get(k):
            title += f", {first[k]}"
    title += "".join(f", {k} {first[k]}" for k in ("starts", "seed") if k not in shown and first.get(k) is not None)
    if first.get("objective_name"):
        title += f"; objective = {first['objective_name']}"
    notes = []
    if "status" in shown and any(r.get("status") == "failed" for r in rows):
        notes.append("failed: no value (a discipline raised or gave NaN, or the MDA did not converge; the bag keeps "
                     "no reason)")
    if left:
        notes.append(f"{len(left)} more column{'s' if len(left) > 1 else ''} "
                     f"({', '.join(left)}): --csv FILE has all")
    caption = "\n".join(notes) or None
    table = Table(title=title, caption=caption)
    for col in shown:
        q, u = _header(col, units)
        table.add_column(f"{q}\n{u}" if u else q, justify="left" if col in ("formulation", "optimizer") else "right",
                         no_wrap=True)
    for i in range(len(rows)):
        table.add_row(*[cells[c][i] for c in shown])
    console = Console(file=out, width=max(width or 0, used, 40))
    console.print(table)


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)
