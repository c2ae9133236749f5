"""Before/after: figures of several runs of one bench on two trees, side by side, as one result file
that scripts/render_bench.py renders (one table: each figure "before" and "after", median and
range over the runs, and the load average each run ended with).

Each input file is one run (bench/results format: ``figures`` with ``what``, ``unit``, ``median``);
a run's value of a figure is that file's median. Run the benches alternately on the same host
(before, after, after, before, ...), under the bench lock, then:

    python bench/compare.py --bench "bench_ros before/after" --before b1.json b2.json \
        --after a1.json a2.json [--match "full MDA" --match ...] --json /tmp/before_after.json

``--append`` adds the table to the --json file if it exists (several benches in one file): each
row then starts with its --bench title, and the file's title lists them all.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import time
from pathlib import Path


def _runs(files: list[Path]) -> tuple[dict[str, tuple[str, list[float]]], list[float]]:
    figures: dict[str, tuple[str, list[float]]] = {}
    loads = []
    for f in files:
        d = json.loads(f.read_text(encoding="utf-8"))
        load = (d.get("host") or {}).get("load_average_1min")
        if load is not None:
            loads.append(float(load))
        for fig in d["figures"]:
            figures.setdefault(fig["what"], (fig["unit"], []))[1].append(float(fig["median"]))
    return figures, loads


def _row(what: str, unit: str, runs: list[float]) -> dict:
    return {"what": what, "unit": unit, "runs": runs, "median": statistics.median(runs),
            "min": min(runs), "max": max(runs)}


def compare(before: list[Path], after: list[Path], match: list[str]) -> list[dict]:
    b, b_load = _runs(before)
    a, a_load = _runs(after)
    rows = []
    for what, (unit, runs) in b.items():
        if what not in a or (match and not any(m in what for m in match)):
            continue
        rows.append(_row(f"{what} — before", unit, runs))
        rows.append(_row(f"{what} — after", unit, a[what][1]))
    if b_load and a_load:
        rows.append(_row("load average (1 min) at the end of each run — before", "", b_load))
        rows.append(_row("load average (1 min) at the end of each run — after", "", a_load))
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bench", required=True, help="the table's title")
    ap.add_argument("--before", nargs="+", type=Path, required=True)
    ap.add_argument("--after", nargs="+", type=Path, required=True)
    ap.add_argument("--match", action="append", default=[], help="keep only figures containing this (repeatable)")
    ap.add_argument("--command", default="", help="how the runs were made (shown with the table)")
    ap.add_argument("--json", type=Path, required=True)
    ap.add_argument("--append", action="store_true", help="add to --json if it exists, rows named by --bench")
    args = ap.parse_args(argv)
    figures = compare(args.before, args.after, args.match)
    if not figures:
        raise SystemExit("no figure is in both sets (or none matches --match)")
    _, loads = _runs(args.before + args.after)
    title, command = args.bench, args.command
    if args.append:
        figures = [dict(f, what=f"{args.bench}: {f['what']}") for f in figures]
        if args.json.exists():
            old = json.loads(args.json.read_text(encoding="utf-8"))
            title, command = f"{old['bench']}; {title}", "; ".join(c for c in (old["command"], command) if c)
            figures = old["figures"] + figures
            loads += [old["host"]["load_average_1min"]] if old["host"]["load_average_1min"] is not None else []
    doc = {"bench": title, "command": command, "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
           "host": {"cpus": os.cpu_count(), "load_average_1min": max(loads) if loads else None,
                    "python": platform.python_version()},
           "figures": figures}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")
    print(f"{args.json}: {len(figures)} rows")


if __name__ == "__main__":
    main()
