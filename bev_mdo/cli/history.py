"""``bev-mdo history BAG [--csv FILE]``: the optimisation history of a recorded run."""
from __future__ import annotations

import sys


def register(subparsers) -> None:
    parser = subparsers.add_parser("history", help="print the optimisation history of a bag")
    parser.add_argument("bag", help="bag directory or .mcap file")
    parser.add_argument("--csv", metavar="FILE", help="write the history as CSV ('-' for stdout)")
    parser.add_argument("--run-id", help="this run (default: the bag's own run; needed for a recording of "
                                         "several runs)")
    parser.add_argument("--key-file", help="key that signed the run (default: the ros.sign_key_file named in "
                                           "the bag's config)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from bev_mdo.bag.history import flat_rows, history, to_csv
    from bev_mdo.bag.reader import open_bag

    bag = open_bag(args.bag)
    if bag.truncated:
        print(bag.recovery_note(), file=sys.stderr)
    from bev_mdo.bag.history import check_note

    checks: dict = {}
    rows = history(bag, run_id=args.run_id, key_file=args.key_file, checks=checks)
    if check_note(checks):
        print(f"{args.bag}: {check_note(checks)}", file=sys.stderr)
    if args.csv:
        text = to_csv(rows)
        if args.csv == "-":
            sys.stdout.write(text)
        else:
            with open(args.csv, "w", encoding="utf-8") as f:
                f.write(text)
            print(f"wrote {len(rows)} iterations to {args.csv}")
        return 0
    _print_table(flat_rows(rows))
    return 0


def _print_table(rows: list[dict]) -> None:
    from rich.console import Console
    from rich.table import Table

    skip = {"run_id", "sequence", "objective_name", "wall_time_s"}
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns and k not in skip]
    table = Table(title=f"{len(rows)} iterations")
    for col in columns:
        table.add_column(col, justify="left" if col in ("formulation", "optimizer") else "right",
                         no_wrap=True)
    cells = [[_fmt(row.get(c, "")) for c in columns] for row in rows]
    for row in cells:
        table.add_row(*row)
    # full width when piped, so no column is cut (a terminal keeps its own width)
    need = sum(max([len(c)] + [len(r[i]) for r in cells]) + 3 for i, c in enumerate(columns)) + 1
    console = Console()
    if not sys.stdout.isatty():
        console = Console(file=sys.stdout, width=max(80, need))
    console.print(table)


def _fmt(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)
