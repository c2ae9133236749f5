"""bench/compare.py: several runs per side of a bench become one before/after table (median and
range per side); --append puts several benches' tables into one result file."""
from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
import _results  # noqa: E402

spec = importlib.util.spec_from_file_location("bench_compare", ROOT / "bench" / "compare.py")
bench_compare = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench_compare)


def _runs(tmp_path: Path, side: str, values: list[float]) -> list[Path]:
    out = []
    for k, v in enumerate(values):
        p = tmp_path / f"{side}_{k}.json"
        figs = [_results.figure("latency p50", "µs", [v, v + 100.0])]  # the run's value: its median, v + 50
        figs += [_results.figure("only in the old tree", "µs", [1.0])] if side == "b" else []
        _results.write("demo", figs, command="demo", path=p)
        out.append(p)
    return out


def test_one_bench_gives_median_and_range_of_the_run_medians_per_side(tmp_path):
    out = tmp_path / "cmp.json"
    bench_compare.main(["--bench", "demo before/after", "--before", *map(str, _runs(tmp_path, "b", [10.0, 30.0, 20.0])),
                        "--after", *map(str, _runs(tmp_path, "a", [40.0, 50.0])), "--json", str(out)])
    d = json.loads(out.read_text())
    rows = {f["what"]: f for f in d["figures"]}
    before, after = rows["latency p50 — before"], rows["latency p50 — after"]
    assert (before["median"], before["min"], before["max"], len(before["runs"])) == (70.0, 60.0, 80.0, 3)
    assert (after["median"], after["min"], after["max"], len(after["runs"])) == (95.0, 90.0, 100.0, 2)
    assert d["bench"] == "demo before/after" and "load average (1 min) at the end of each run — after" in rows
    assert not any("only in the old tree" in w for w in rows)  # a figure must be on both sides


def test_append_puts_several_benches_in_one_file_rows_named_by_bench(tmp_path):
    out = tmp_path / "cmp.json"
    b, a = _runs(tmp_path, "b", [10.0, 30.0]), _runs(tmp_path, "a", [40.0, 50.0])
    for bench in ("first", "second"):
        bench_compare.main(["--bench", bench, "--before", *map(str, b), "--after", *map(str, a), "--json", str(out),
                            "--command", f"run {bench}", "--append"])
    d = json.loads(out.read_text())
    whats = [f["what"] for f in d["figures"]]
    assert d["bench"] == "first; second" and d["command"] == "run first; run second"
    for bench in ("first", "second"):
        assert [w for w in whats if w.startswith(bench + ": ")] == [
            f"{bench}: latency p50 — before", f"{bench}: latency p50 — after",
            f"{bench}: load average (1 min) at the end of each run — before",
            f"{bench}: load average (1 min) at the end of each run — after"]
    assert len(whats) == 8 and d["figures"][0]["median"] == 70.0
