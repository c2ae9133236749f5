#!/usr/bin/env python3
"""Render the benchmark figures of ``bench/results/*.json`` into docs/performance.md.

The section between ``<!-- bench:begin -->`` and ``<!-- bench:end -->`` is replaced by one table
per result file (what, median and range over the runs, unit, target) with, under it, the command
that produced it, its date and the host's load; results of a bench that does not write figures
(``bench/_results.py``'s format) are listed after the tables with their file. Nothing in the
section is written by hand. A result's ``tables`` (``{"title", "columns", "rows"}``, e.g. the
accuracy table of bench_validate) are rendered under its figures, and also into any section
``<!-- bench-tables:NAME:begin -->`` ... ``<!-- bench-tables:NAME:end -->`` of ``--tables-doc``
(default, when ``--doc`` is not given: docs/validation.md). ``--check`` exits 1 if a document is
not what the results render to (test/test_render_bench.py runs that).

    python scripts/render_bench.py [--check] [--results bench/results] [--doc docs/performance.md] [--tables-doc DOC]
"""
from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
BEGIN, END = "<!-- bench:begin -->", "<!-- bench:end -->"


def fmt(v: float) -> str:
    a = abs(v)
    if a >= 1e5:
        return f"{v:,.0f}".replace(",", " ")
    if a >= 100:
        return f"{v:.0f}"
    if a >= 1:
        return f"{v:.3g}"
    return f"{v:.3g}"


def _where(p: Path) -> str:
    return str(p.relative_to(ROOT) if p.is_relative_to(ROOT) else p)


def render_tables(d: dict) -> list[str]:
    """A result's tables (title, columns, rows; None shown as -) as Markdown lines."""
    out = []
    for t in d.get("tables", []):
        out += [f"**{t['title']}**", "", "| " + " | ".join(t["columns"]) + " |",
                "|" + "|".join("---" if i < 2 else "---:" for i in range(len(t["columns"]))) + "|"]
        out += ["| " + " | ".join("-" if v is None else (f"{v:.2f}" if isinstance(v, float) else str(v)) for v in row) + " |"
                for row in t["rows"]]
        out.append("")
    return out


def _load(results_dir: Path) -> list[tuple[Path, object]]:
    out = []
    for p in sorted(results_dir.glob("*.json")):
        try:
            out.append((p, json.loads(p.read_text(encoding="utf-8"))))
        except json.JSONDecodeError as exc:
            raise SystemExit(f"{p}: not JSON ({exc})")
    return out


def splice_tables(doc: str, results_dir: Path) -> str:
    """Fill every ``bench-tables:NAME`` section of ``doc`` with the tables of result NAME."""
    by_name = {d.get("bench", p.stem): d for p, d in _load(results_dir) if isinstance(d, dict)}

    def fill(m: re.Match) -> str:
        name, d = m.group(1), by_name.get(m.group(1))
        body = ("\n".join(render_tables(d)).rstrip() + f"\n\n`{d.get('command', '')}` — {d.get('date_utc', '?')} UTC"
                if d else f"_No tables: run bench/{name}.py._")
        return f"<!-- bench-tables:{name}:begin -->\n{body}\n<!-- bench-tables:{name}:end -->"

    return re.sub(r"<!-- bench-tables:([\w.-]+):begin -->.*?<!-- bench-tables:\1:end -->", fill, doc, flags=re.S)


def render(results_dir: Path) -> str:
    docs, other = [], []
    for p, d in _load(results_dir):
        (docs if isinstance(d, dict) and "figures" in d else other).append((p, d))
    if not docs and not other:
        return "_No results yet: run the benches (they write bench/results/*.json), then this script._\n"
    out = []
    for p, d in docs:
        host = d.get("host", {})
        out += [f"### {d.get('bench', p.stem)}",
                "| what | median | range (runs) | unit | target |", "|---|---:|---:|---|---|"]
        for f in d["figures"]:
            rng = f"{fmt(f['min'])}–{fmt(f['max'])} ({len(f['runs'])})" if len(f["runs"]) > 1 else f"({len(f['runs'])})"
            out.append(f"| {f['what']} | {fmt(f['median'])} | {rng} | {f['unit']} | {f.get('target', '')} |")
        out += [""] + render_tables(d)
        out += [f"`{d.get('command', '')}` — {d.get('date_utc', '?')} UTC, {host.get('cpus', '?')} CPUs, "
                    f"load average {host.get('load_average_1min', '?')} at the end; `{_where(p)}`", ""]
    if other:
        out += ["### Results in a bench's own format", "",
                "Read with the bench's own docstring: " + "; ".join(
                    f"`{_where(p)}` ({', '.join(list(d)[:4]) if isinstance(d, dict) else type(d).__name__})"
                    for p, d in other) + ".", ""]
    return "\n".join(out)


def splice(doc: str, body: str) -> str:
    if BEGIN not in doc or END not in doc:
        raise SystemExit(f"the document has no {BEGIN} ... {END} section")
    head, rest = doc.split(BEGIN, 1)
    _, tail = rest.split(END, 1)
    return f"{head}{BEGIN}\n{body.rstrip()}\n{END}{tail}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", default=str(ROOT / "bench" / "results"))
    ap.add_argument("--doc", default=str(ROOT / "docs" / "performance.md"))
    ap.add_argument("--tables-doc", default=None,
                    help="also fill its bench-tables sections (default without --doc: docs/validation.md)")
    ap.add_argument("--check", action="store_true", help="exit 1 if the document is stale")
    args = ap.parse_args(argv)
    results = Path(args.results)
    doc_path = Path(args.doc)
    doc = doc_path.read_text(encoding="utf-8")
    todo = [(doc_path, doc, splice(doc, render(results)))]
    tables_doc = args.tables_doc or (None if "--doc" in (argv if argv is not None else sys.argv) else
                                     ROOT / "docs" / "validation.md")
    if tables_doc:
        t = Path(tables_doc).read_text(encoding="utf-8")
        todo.append((Path(tables_doc), t, splice_tables(t, results)))
    if args.check:
        stale = [str(p) for p, old, new in todo if new != old]
        for p in stale:
            print(f"{p} is stale: run python scripts/render_bench.py", file=sys.stderr)
        return 1 if stale else 0
    for p, old, new in todo:
        p.write_text(new, encoding="utf-8")
    print(f"rendered {len(list(results.glob('*.json')))} result files into {', '.join(str(p) for p, _, _ in todo)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
