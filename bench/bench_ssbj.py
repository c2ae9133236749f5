"""Sobieski's SSBJ (examples/ssbj/), MDF and IDF, in process and over ROS, side by side in ONE run.

Each with the disciplines' analytic partials (the configs' default) and with finite differences.

1. in process: ``run_optimization`` with ``InProcessEvaluator`` on ``examples/ssbj/ssbj_{mdf,idf}.yaml``
   (the user-discipline interface only); time = the whole call (disciplines built, optimisation).
2. over ROS: four node processes (one per discipline, started once), the coordinator in this
   process; time = the coordinator's ``run`` from its start to its result (discovery of the new
   coordinator, handshake, optimisation), and separately the optimisation alone
   (``RunResult.wall_time_s``). Node start-up is excluded.
3. with ``--cli-repeat N``: the whole ``bev-mdo optimize`` command (analytic partials), start to
   result, over ROS (node processes started and stopped) and in process.

One untimed warm-up run per method, then ``--repeat`` timed runs interleaved round by round (the
host is noisy): median, min and max. The 1-minute load average is recorded before and after.
Writes bench/results/bench_ssbj.json; asserts nothing about time.

    .venv/bin/python bench/bench_ssbj.py [--repeat 5] [--no-ros] [--domain-id 146] [--cli-repeat 3]
    (take /tmp/bev_bench.lock and /tmp/bev_ros.lock around it on a shared host)
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

import _results  # noqa: E402
from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402

EXAMPLE = REPO / "examples" / "ssbj"
OPTIMUM_RANGE = 3963.3800123


def _stats(times: list[float]) -> dict:
    return {"times_s": times, "median_s": statistics.median(times), "min_s": min(times), "max_s": max(times)}


def _summary(r) -> dict:
    return {"objective": r.objective, "feasible": r.feasible, "iterations": r.iterations,
            "mda_evaluations": r.mda_evaluations, "discipline_evaluations": r.discipline_evaluations,
            "points_evaluated": r.points_evaluated, "gradients": r.gradients}


def _config(formulation: str, derivatives: str) -> dict:
    import yaml

    raw = yaml.safe_load((EXAMPLE / f"ssbj_{formulation}.yaml").read_text())
    raw["optimizer"]["derivatives"] = derivatives
    raw["search_path"] = [str(EXAMPLE)]
    return load_config(raw)


class InProcess:
    def __init__(self, formulation: str, derivatives: str):
        self.name = f"{formulation.upper()} {derivatives} in process"
        self.config = _config(formulation, derivatives)

    def once(self) -> dict:
        t0 = time.perf_counter()
        r = run_optimization(self.config, InProcessEvaluator(resolve_disciplines(self.config)))
        return {"wall_s": time.perf_counter() - t0, "optimisation_s": r.wall_time_s, **_summary(r)}


class Ros:
    def __init__(self, formulation: str, derivatives: str, ctx):
        self.ctx = ctx
        self.name = f"{formulation.upper()} {derivatives} over ROS"
        self.config = _config(formulation, derivatives)

    def once(self) -> dict:
        from bev_mdo.ros import coordinator_node

        t0 = time.perf_counter()
        r, stats = coordinator_node.run(self.config, context=self.ctx)
        return {"wall_s": time.perf_counter() - t0, "optimisation_s": r.wall_time_s, **_summary(r),
                "retried": stats["retried"], "dropped": stats["dropped"]}


def _cli(repeat: int, domain: int) -> list[dict]:
    """The whole command a user runs, start to result, interleaved round by round."""
    import subprocess

    from bev_mdo.testing import ros_env

    env = {**os.environ, **ros_env(domain)}
    cases = [(f, t) for f in ("mdf", "idf") for t in ("ros", "inprocess")]
    runs: dict[tuple, list] = {c: [] for c in cases}
    for _ in range(repeat):
        for f, t in cases:
            t0 = time.perf_counter()
            p = subprocess.run([sys.executable, "-m", "bev_mdo", "optimize", str(EXAMPLE / f"ssbj_{f}.yaml"),
                                "--transport", t, *(["--domain-id", str(domain)] if t == "ros" else []),
                                "--json", "--no-record", "--quiet"],
                               env=env, capture_output=True, text=True, timeout=600)
            wall = time.perf_counter() - t0
            doc = json.loads(p.stdout) if p.returncode == 0 else {}
            runs[(f, t)].append({"wall_s": wall, "rc": p.returncode, "objective": doc.get("objective"),
                                 "optimisation_s": doc.get("wall_time_s"),
                                 "retried": doc.get("retried_requests")})
    return [{"config": f"examples/ssbj/ssbj_{f}.yaml", "transport": t, **_stats([r["wall_s"] for r in rs]),
             "optimisation_only": _stats([r["optimisation_s"] or float("nan") for r in rs]),
             "exit_codes": [r["rc"] for r in rs], "objectives": [r["objective"] for r in rs],
             "retried": [r["retried"] for r in rs]} for (f, t), rs in runs.items()]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-ros", dest="ros", action="store_false")
    ap.add_argument("--domain-id", type=int, default=146)
    ap.add_argument("--cli-repeat", type=int, default=0,
                    help="also time the whole `bev-mdo optimize CONFIG --json --no-record --quiet` command "
                         "(node processes started and stopped over ROS) this many times per config and transport")
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "bench_ssbj.json"))
    args = ap.parse_args(argv)
    load_before = os.getloadavg()
    variants = [(f, d) for f in ("mdf", "idf") for d in ("analytic", "fd")]
    methods = [InProcess(f, d) for f, d in variants]
    launcher = ctx = None
    if args.ros:
        import rclpy

        from bev_mdo.launcher import Launcher
        from bev_mdo.processes import discipline_argv
        from bev_mdo.testing import ros_env

        env = ros_env(args.domain_id)
        os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
        os.environ.pop("ROS_LOCALHOST_ONLY", None)
        log_dir = Path("/tmp") / f"bench_ssbj_{os.getpid()}"
        log_dir.mkdir(parents=True, exist_ok=True)
        launcher = Launcher(env, log_dir=log_dir)
        for name in ("structure", "aerodynamics", "propulsion", "mission"):
            launcher.add(name, discipline_argv(name, str(EXAMPLE / "ssbj_mdf.yaml")))
        launcher.supervise()
        ctx = rclpy.context.Context()
        rclpy.init(context=ctx)
        methods += [Ros(f, d, ctx) for f, d in variants]
    try:
        runs = _results.interleaved(methods, args.repeat)
    finally:
        if ctx is not None:
            import rclpy

            rclpy.shutdown(context=ctx)
        if launcher is not None:
            launcher.stop()
    out = {"bench": "bench_ssbj", "command": "python bench/bench_ssbj.py " + " ".join(sys.argv[1:]),
           "date_utc": time.strftime("%Y-%m-%d %H:%M", time.gmtime()), "host_cpus": os.cpu_count(),
           "load_average_before": [round(v, 2) for v in load_before],
           "load_average_after": [round(v, 2) for v in os.getloadavg()],
           "repeat": args.repeat, "optimizer": "SLSQP", "optimum_range": OPTIMUM_RANGE,
           "methods": []}
    for m in methods:
        rs = runs[m.name]
        last = rs[-1]
        out["methods"].append({"method": m.name, **_stats([r["wall_s"] for r in rs]),
                               "optimisation_only": _stats([r["optimisation_s"] for r in rs]),
                               **{k: v for k, v in last.items() if k not in ("wall_s", "optimisation_s")},
                               "same_result_every_run": len({r["objective"] for r in rs}) == 1})
    if args.cli_repeat:
        out["start_to_result"] = _cli(args.cli_repeat, args.domain_id)
    out["load_average_after"] = [round(v, 2) for v in os.getloadavg()]
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2, default=float) + "\n")
    print(f"SSBJ, {args.repeat} runs each (interleaved); load average before {out['load_average_before']}, "
          f"after {out['load_average_after']}")
    print(f"{'method':27s} {'median s':>9s} {'min':>7s} {'max':>7s} {'optim. s':>9s} {'range':>12s} "
          f"{'iter':>5s} {'MDAs':>5s}  evaluations")
    for row in out["methods"]:
        print(f"{row['method']:27s} {row['median_s']:9.3f} {row['min_s']:7.3f} {row['max_s']:7.3f} "
              f"{row['optimisation_only']['median_s']:9.3f} {row['objective']:12.6f} {row['iterations']:5d} "
              f"{row['mda_evaluations']:5d}  {row['discipline_evaluations']}")
    for row in out.get("start_to_result", []):
        print(f"start to result: {row['config']} {row['transport']:9s} median {row['median_s']:.2f} s "
              f"[{row['min_s']:.2f}, {row['max_s']:.2f}] exit {row['exit_codes']} retried {row['retried']}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
