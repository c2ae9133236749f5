"""What the end-of-run first-order check costs beside the optimisation, and multi-start throughput.

1. First-order check (bev_mdo/mdo/first_order.py via driver.end_point_check): for Sellar MDF and IDF
   (examples/sellar) and the BEV problem (config/leaf_nedc.yaml), with SLSQP (the check reuses the
   last gradient) and COBYQA (the check evaluates one stencil), in process and, unless --no-ros, over
   ROS (three Sellar node processes, coordinator here; Sellar only). Per run: the optimisation's wall
   time (RunResult.wall_time_s, which includes the check), the check's own wall time and the points
   it evaluated.
2. Multi-start (bev_mdo/mdo/multistart.py): --starts N Latin-hypercube starts with SLSQP on Sellar MDF
   and the BEV problem in process, and on Sellar MDF over ROS, one seed per repeat, the starts batched
   together (lockstep.py, the default) and one after another, side by side: designs evaluated per
   second (all starts' points / wall time) and the share of starts that reached the best point.

Every case is repeated --repeat times, interleaved round by round (the host is noisy); median, min and
max are reported. It asserts nothing about time.

    flock /tmp/bev_ros_tests.lock .venv/bin/python bench/bench_optimum.py --repeat 5 [--no-ros] [--domain-id 211]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

import _results  # noqa: E402

from bev_mdo.config import discipline_names, load_config, resolve_disciplines, run_settings  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.mdo.multistart import run_starts  # noqa: E402

CONFIGS = {"sellar_mdf": REPO / "examples" / "sellar" / "sellar_mdf.yaml",
           "sellar_idf": REPO / "examples" / "sellar" / "sellar_idf.yaml",
           "leaf_nedc": REPO / "config" / "leaf_nedc.yaml"}


def _stats(xs: list[float]) -> dict:
    return {"median": statistics.median(xs), "min": min(xs), "max": max(xs), "values": xs}


def _check_case(config_name: str, optimizer: str, evaluator_factory, run=None) -> dict:
    config = load_config(CONFIGS[config_name])
    if run is None:
        r = run_optimization(config, evaluator_factory(config), optimizer=optimizer)
    else:
        r = run(config, optimizer)
    cost = r.first_order["cost"]
    return {"optimisation_s": r.wall_time_s, "check_s": cost["wall_time_s"], "check_points": cost["points"],
            "points": r.points_evaluated, "verdict": r.verdict, "objective": r.objective}


def _in_process(config):
    return InProcessEvaluator(resolve_disciplines(config))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--no-ros", dest="ros", action="store_false")
    ap.add_argument("--domain-id", type=int, default=211)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "bench_optimum.json"))
    args = ap.parse_args(argv)
    load_before = os.getloadavg()
    cases = [(c, o, "inprocess") for c in CONFIGS for o in ("SLSQP", "COBYQA")]
    nodes = None
    if args.ros:
        from bench_sellar import RosNodes

        from bev_mdo.ros import coordinator_node

        log_dir = Path("/tmp") / f"bench_optimum_{os.getpid()}"
        log_dir.mkdir(parents=True, exist_ok=True)
        nodes = RosNodes(args.domain_id, log_dir)
        cases += [(c, o, "ros") for c in ("sellar_mdf", "sellar_idf") for o in ("SLSQP", "COBYQA")]

        def over_ros(config, optimizer):
            config["ros"]["domain_id"] = args.domain_id
            return coordinator_node.run(config, context=nodes.ctx, optimizer=optimizer)[0]
    check: dict[tuple, list[dict]] = {c: [] for c in cases}
    multi_cases = [(c, t, b) for c, t in [("sellar_mdf", "inprocess"), ("leaf_nedc", "inprocess")]
                   + ([("sellar_mdf", "ros")] if args.ros else []) for b in (True, False)]
    multi: dict[tuple, list[dict]] = {c: [] for c in multi_cases}
    try:
        for k in range(args.repeat):
            for case in cases:
                c, o, transport = case
                check[case].append(_check_case(c, o, _in_process, None if transport == "inprocess" else over_ros))
            for case in multi:
                c, transport, batched = case
                config = load_config(CONFIGS[c])
                if transport == "ros":
                    config["ros"]["domain_id"] = args.domain_id
                    node = coordinator_node.CoordinatorNode(config, f"bench{k}{int(batched)}", context=nodes.ctx)
                    node.evaluator.wait_for_disciplines(discipline_names(config), node.discovery_wait_s)
                    evaluator = node.evaluator
                else:
                    evaluator = _in_process(config)
                t0 = time.perf_counter()
                try:
                    r = run_starts(run_settings(config), evaluator, args.starts, seed=k, batched=batched)
                finally:
                    wall = time.perf_counter() - t0
                    if transport == "ros":
                        node.evaluator.close()
                        node.destroy_node()
                ms = r.multistart
                multi[case].append({"wall_s": wall, "designs_per_s": r.points_evaluated / wall,
                                 "share_reached_best": ms["reached_best"] / ms["starts"], "objective": r.objective,
                                 "verdicts": [x["verdict"] for x in ms["results"]]})
    finally:
        if nodes is not None:
            nodes.close()
    load_after = os.getloadavg()
    rows, figures = [], []
    print(f"first-order check beside the optimisation, {args.repeat} runs each; load {load_before[0]:.2f} -> "
          f"{load_after[0]:.2f}")
    print(f"{'case':36s} {'optimisation ms':>22s} {'check ms':>20s} {'share':>7s} {'check pts/run pts':>18s} verdict")
    for case, runs in check.items():
        opt, chk = _stats([1e3 * r["optimisation_s"] for r in runs]), _stats([1e3 * r["check_s"] for r in runs])
        share = statistics.median(r["check_s"] / r["optimisation_s"] for r in runs)
        name = f"{case[0]} {case[1]} {case[2]}"
        rows.append({"case": name, "optimisation_ms": opt, "check_ms": chk, "check_share_median": share,
                     "check_points": runs[-1]["check_points"], "points": runs[-1]["points"],
                     "verdicts": sorted({r["verdict"] for r in runs})})
        figures.append(_results.figure(f"{name}: first-order check, share of the run's wall time", "%",
                                       [100 * r["check_s"] / r["optimisation_s"] for r in runs]))
        print(f"{name:36s} {opt['median']:8.1f} ({opt['min']:6.1f}-{opt['max']:6.1f}) {chk['median']:7.2f} "
              f"({chk['min']:5.2f}-{chk['max']:5.2f}) {100 * share:6.2f}% {runs[-1]['check_points']:>8d}/"
              f"{runs[-1]['points']:<8d} {','.join(rows[-1]['verdicts'])}")
    print(f"\nmulti-start, {args.starts} starts (SLSQP, seeds 0..{args.repeat - 1})")
    mrows = []
    for (c, transport, batched), runs in multi.items():
        dps, share = _stats([r["designs_per_s"] for r in runs]), _stats([r["share_reached_best"] for r in runs])
        how = "batched" if batched else "one after another"
        mrows.append({"config": c, "transport": transport, "batched": batched, "starts": args.starts,
                      "designs_per_s": dps, "share_reached_best": share,
                      "wall_s": _stats([r["wall_s"] for r in runs]), "objectives": [r["objective"] for r in runs]})
        figures.append(_results.figure(f"{c} {transport}: multi-start designs per second ({args.starts} starts, {how})",
                                       "1/s", dps["values"]))
        if batched:
            figures.append(_results.figure(f"{c} {transport}: share of {args.starts} starts reaching the best point",
                                           "%", [100 * v for v in share["values"]]))
        print(f"{c:12s} {transport:9s} {how:17s} designs/s {dps['median']:8.1f} ({dps['min']:.1f}-{dps['max']:.1f})"
              f"  share reaching the best {share['median']:.2f} ({share['min']:.2f}-{share['max']:.2f})")
    extra = {"repeat": args.repeat, "starts": args.starts, "load_average_before": [round(v, 2) for v in load_before],
             "load_average_after": [round(v, 2) for v in load_after], "check": rows, "multistart": mrows}
    _results.write("bench_optimum", figures, path=args.json, extra=extra)
    return 0


if __name__ == "__main__":
    sys.exit(main())
