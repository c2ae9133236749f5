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
