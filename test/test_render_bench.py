"""Benchmark figures in docs/performance.md come from bench/results/*.json, not from a hand."""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
spec = importlib.util.spec_from_file_location("render_bench", ROOT / "scripts" / "render_bench.py")
render_bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(render_bench)
sys.path.insert(0, str(ROOT / "bench"))
import _results  # noqa: E402


def test_the_performance_doc_is_what_the_committed_results_render_to():
    assert render_bench.main(["--check"]) == 0


def test_render_shows_median_range_target_and_command(tmp_path):
    res = tmp_path / "results"
    _results.write("demo", [_results.figure("thing per second", "designs/s", [3.0, 1.0, 2.0], ">= 1")],
                   command="python bench/demo.py --runs 3", path=res / "demo.json")
    doc = tmp_path / "perf.md"
    doc.write_text(f"# P\n\n{render_bench.BEGIN}\nold hand-written figure\n{render_bench.END}\ntail\n")
    assert render_bench.main(["--results", str(res), "--doc", str(doc), "--check"]) == 1  # stale
    assert render_bench.main(["--results", str(res), "--doc", str(doc)]) == 0
    text = doc.read_text()
    assert "old hand-written figure" not in text and text.endswith("tail\n")
    assert "| thing per second | 2 | 1–3 (3) | designs/s | >= 1 |" in text
    assert "`python bench/demo.py --runs 3`" in text
    assert json.loads((res / "demo.json").read_text())["figures"][0]["median"] == 2.0


def test_tables_render_under_the_figures_and_into_the_tables_doc(tmp_path):
    res = tmp_path / "results"
    table = {"title": "accuracy", "columns": ["model", "how", "MAPE %"], "rows": [["a", "fit", 7.0], ["b", "none", None]]}
    _results.write("demo", [_results.figure("x", "ms", [1.0])], command="python bench/demo.py",
                   path=res / "demo.json", extra={"tables": [table]})
    perf, tables = tmp_path / "perf.md", tmp_path / "validation.md"
    perf.write_text(f"{render_bench.BEGIN}\n{render_bench.END}\n")
    tables.write_text("# V\n<!-- bench-tables:demo:begin -->\nold\n<!-- bench-tables:demo:end -->\ntail\n")
    argv = ["--results", str(res), "--doc", str(perf), "--tables-doc", str(tables)]
    assert render_bench.main(argv + ["--check"]) == 1
    assert render_bench.main(argv) == 0 and render_bench.main(argv + ["--check"]) == 0
    for doc in (perf, tables):
        text = doc.read_text()
        assert "**accuracy**" in text and "| a | fit | 7.00 |" in text and "| b | none | - |" in text
    assert "old" not in tables.read_text() and tables.read_text().endswith("tail\n")
