"""Analytic partials against finite differences on the BEV default problem (config/leaf_nedc.yaml).

Both derivative modes of the same MDF / SLSQP run, side by side in one process, alternating
run by run (the host is noisy):

* ``fd``: every gradient is a finite-difference stencil of whole MDAs (the point + 3 points);
* ``analytic``: vehicle_mass, range, motor_speed and cost give analytic partials, energy and
  acceleration (no partials) are differenced alone, and the totals come from the chain rule.

Reported per mode and transport: optimiser iterations, MDA evaluations, discipline evaluations
(per discipline and in total), gradients, the optimum, and the wall time of the optimisation
(RunResult.wall_time_s: median, min, max over the runs). Over ROS six discipline node processes
(domain --domain-id, default 142, localhost-only discovery) serve both modes; the coordinator
runs here (``coordinator_node.run``: data-flow MDAs, warm-up before the timed optimisation).
Take the shared locks (bench, and ROS for the ROS part):

    flock /tmp/bev_bench.lock flock /tmp/bev_ros.lock python bench/bench_partials.py --repeat 7
        [--no-ros] [--domain-id 142]

Writes bench/results/bench_partials.json: the per-mode details as before, plus ``figures`` (the
wall times, rendered into docs/performance.md by scripts/render_bench.py) and the 1-minute load
average before and after.
"""
from __future__ import annotations

import argparse
import copy
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402

CONFIG = REPO / "config" / "leaf_nedc.yaml"
MODES = ("fd", "analytic")


def _config(mode: str, domain: int | None = None) -> dict:
    cfg = copy.deepcopy(load_config(CONFIG))
    cfg["optimizer"]["derivatives"] = mode
    if domain is not None:
        cfg["ros"]["domain_id"] = domain
    return cfg


def _summary(runs: list) -> dict:
    r = runs[-1]
    times = [x.wall_time_s for x in runs]
    return {"iterations": r.iterations, "mda_evaluations": r.mda_evaluations,
            "discipline_evaluations": r.discipline_evaluations,
            "discipline_evaluations_total": sum(r.discipline_evaluations.values()),
            "gradients": r.gradients, "feasible": r.feasible, "objective": r.objective, "design": r.design,
            "runs": len(runs), "wall_time_s": times, "median_s": statistics.median(times),
            "min_s": min(times), "max_s": max(times)}


def bench_inprocess(repeat: int) -> dict:
    runs = {m: [] for m in MODES}
    for i in range(repeat + 1):  # first round: warm-up (imports, caches), not kept
        for m in MODES:
            cfg = _config(m)
            r = run_optimization(cfg, InProcessEvaluator(resolve_disciplines(cfg)))
            if i:
                runs[m].append(r)
    return {m: _summary(runs[m]) for m in MODES}


def bench_ros(repeat: int, domain: int, log_dir: Path) -> dict:
    for k in ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER"):
        os.environ.pop(k, None)
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy

    from bev_mdo.ros import coordinator_node
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.testing import ros_env

    env = ros_env(domain)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"] == str(domain)
    launcher = Launcher(env, log_dir=log_dir)
    base = _config("analytic", domain)
    path = log_dir / "leaf.yaml"
    import yaml

    path.write_text(yaml.safe_dump(base, sort_keys=False))
    runs = {m: [] for m in MODES}
    retried = {m: 0 for m in MODES}
    ctx = rclpy.context.Context()
    try:
        for d in resolve_disciplines(base):
            launcher.add(d.name, discipline_argv(d.name, str(path)))
        rclpy.init(context=ctx)
        for i in range(repeat + 1):  # first round: discovery and first messages, not kept
            for m in MODES:
                r, stats = coordinator_node.run(_config(m, domain), context=ctx)
                if i:
                    runs[m].append(r)
                    retried[m] += stats["retried"]
    finally:
        if ctx.ok():
            rclpy.shutdown(context=ctx)
        launcher.stop()
    out = {m: {**_summary(runs[m]), "retried": retried[m]} for m in MODES}
    out["node_restarts"] = {n.label: n.restarts for n in launcher.nodes if n.restarts}
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--no-ros", dest="ros", action="store_false")
    ap.add_argument("--domain-id", type=int, default=142)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "bench_partials.json"))
    args = ap.parse_args(argv)
    t0 = time.time()
    load_before = os.getloadavg()
    result = {"problem": "config/leaf_nedc.yaml (MDF, SLSQP)", "repeat": args.repeat,
              "started_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime(t0)),
              "inprocess": bench_inprocess(args.repeat)}
    if args.ros:
        import tempfile

        with tempfile.TemporaryDirectory(prefix="bench_partials_") as d:
            result["ros"] = bench_ros(args.repeat, args.domain_id, Path(d))
    result["load_average_before"] = [round(v, 2) for v in load_before]
    result["load_average_after"] = [round(v, 2) for v in os.getloadavg()]
    sys.path.insert(0, str(REPO / "bench"))
    import _results

    figures = []
    for tr, label in (("inprocess", "in process"), ("ros", "over ROS")):
        for m in MODES:
            s = result.get(tr, {}).get(m)
            if s:
                figures.append(_results.figure(
                    f"BEV default MDF/SLSQP {label}, derivatives {m}: optimisation wall time "
                    f"({s['iterations']} iterations, {s['mda_evaluations']} MDAs, "
                    f"{s['discipline_evaluations_total']} discipline evaluations)", "ms",
                    [1e3 * t for t in s["wall_time_s"]]))
    _results.write("bench_partials", figures, path=args.json, extra=result)
    print(f"{'transport':<10} {'mode':<9} {'iter':>4} {'MDAs':>5} {'disc. evals':>11} {'grads':>5} "
          f"{'median ms':>9} {'min ms':>7} {'max ms':>7}  objective")
    for tr in ("inprocess", "ros"):
        for m in MODES:
            s = result.get(tr, {}).get(m)
            if s:
                print(f"{tr:<10} {m:<9} {s['iterations']:>4} {s['mda_evaluations']:>5} "
                      f"{s['discipline_evaluations_total']:>11} {s['gradients']:>5} {s['median_s'] * 1e3:>9.2f} "
                      f"{s['min_s'] * 1e3:>7.2f} {s['max_s'] * 1e3:>7.2f}  {s['objective']:.10g}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
