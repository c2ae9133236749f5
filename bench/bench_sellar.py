"""Sellar MDF, side by side in ONE run (issue 14, "Benchmark"):

1. OpenMDAO's own Sellar MDF in process: ``openmdao.test_suite.components.sellar_feature.SellarMDA``
   (cycle group with NonlinearBlockGS, discipline partials by FD, ExecComp objective/constraints),
   ``ScipyOptimizeDriver(optimizer="SLSQP", tol=1e-8)``, z in [-10, 10] x [0, 10], x in [0, 10],
   con1 = 3.16 - y1 <= 0, con2 = y2 - 24 <= 0, start z = (5, 2), x = 1 (the OpenMDAO docs' problem).
2. bev_mdo in process: ``examples/sellar/sellar_mdf.yaml`` through ``run_optimization`` with
   ``InProcessEvaluator`` (the user-discipline interface only).
3. bev_mdo over ROS: the same config, one node process per discipline (domain --domain-id,
   localhost-only discovery), the coordinator in this process. Time = the coordinator's
   ``run`` call from its start to its result (the handshake with the running nodes, the
   warm-up and the optimisation; node start-up excluded, it is in bench_sellar_startup.py).

Each method gets one untimed warm-up run, then ``--repeat`` timed runs, interleaved round by round
(the host is noisy): median, min and max are reported. It prints and writes figures; it asserts
nothing about time.

    .venv/bin/python bench/bench_sellar.py [--repeat 7] [--no-ros] [--domain-id 21]
    (take /tmp/bev_ros.lock around it on a shared host)

OpenMDAO is a bench-only dependency: ``pip install -c constraints.txt -r bench/requirements.txt``.
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

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402

CONFIG = REPO / "examples" / "sellar" / "sellar_mdf.yaml"
REF_F = 3.18339395


def _stats(times: list[float]) -> dict:
    return {"times_s": times, "median_s": statistics.median(times), "min_s": min(times), "max_s": max(times)}


class OpenMDAO:
    name = "OpenMDAO SellarMDA (NonlinearBlockGS + SLSQP), in process"

    def __init__(self):
        import openmdao.api as om
        from openmdao.test_suite.components.sellar_feature import SellarMDA

        self.om, self.SellarMDA = om, SellarMDA
        self.version = __import__("openmdao").__version__

    def once(self) -> dict:
        om = self.om
        t0 = time.perf_counter()
        prob = om.Problem(reports=False)
        prob.model = self.SellarMDA()
        prob.driver = om.ScipyOptimizeDriver(optimizer="SLSQP", tol=1e-8, disp=False)
        prob.model.add_design_var("x", lower=0, upper=10)
        prob.model.add_design_var("z", lower=[-10.0, 0.0], upper=[10.0, 10.0])
        prob.model.add_objective("obj")
        prob.model.add_constraint("con1", upper=0)
        prob.model.add_constraint("con2", upper=0)
        prob.setup()
        prob.set_solver_print(level=0)
        prob.set_val("x", 1.0)
        prob.set_val("z", [5.0, 2.0])
        prob.run_driver()
        wall = time.perf_counter() - t0
        z = prob.get_val("z")
        return {"wall_s": wall, "objective": float(prob.get_val("obj")[0]),
                "design": {"z1": float(z[0]), "z2": float(z[1]), "x": float(prob.get_val("x")[0])},
                "iterations": int(prob.driver.iter_count),
                "model_solves": int(prob.model.iter_count)}


class BevInProcess:
    name = "bev_mdo in process (examples/sellar, user-discipline interface)"

    def __init__(self, config):
        self.config = config

    def once(self) -> dict:
        t0 = time.perf_counter()
        ev = InProcessEvaluator(resolve_disciplines(self.config))
        r = run_optimization(self.config, ev)
        wall = time.perf_counter() - t0
        return {"wall_s": wall, "objective": r.objective, "design": r.design, "iterations": r.iterations,
                "mda_evaluations": r.mda_evaluations, "discipline_evaluations": r.discipline_evaluations,
                "feasible": r.feasible}


class BevRos:
    name = "bev_mdo over ROS (3 node processes, coordinator here)"

    def __init__(self, config, domain: int, log_dir: Path):
        import rclpy

        from bev_mdo.ros.launch import Launcher, discipline_argv
        from bev_mdo.testing import ros_env

        env = ros_env(domain)
        os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
        os.environ.pop("ROS_LOCALHOST_ONLY", None)
        self.config = config
        self.launcher = Launcher(env, log_dir=log_dir)
        cfg_path = log_dir / "config.yaml"
        import yaml

        cfg_path.write_text(yaml.safe_dump(config, sort_keys=False))
        for entry in config["disciplines"]:
            self.launcher.add(entry["name"], discipline_argv(entry["name"], str(cfg_path)))
        self.launcher.supervise()
        self.ctx = rclpy.context.Context()
        rclpy.init(context=self.ctx)

    def once(self) -> dict:
        from bev_mdo.ros import coordinator_node

        t0 = time.perf_counter()
        r, stats = coordinator_node.run(self.config, context=self.ctx)
        wall = time.perf_counter() - t0
        return {"wall_s": wall, "optimisation_s": r.wall_time_s, "objective": r.objective, "design": r.design,
                "iterations": r.iterations, "mda_evaluations": r.mda_evaluations,
                "discipline_evaluations": r.discipline_evaluations, "feasible": r.feasible,
                "retried": stats["retried"], "dropped": stats["dropped"]}

    def close(self):
        import rclpy

        rclpy.shutdown(context=self.ctx)
        self.launcher.stop()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--no-ros", dest="ros", action="store_false")
    ap.add_argument("--domain-id", type=int, default=21)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "bench_sellar.json"))
    args = ap.parse_args(argv)
    config = load_config(CONFIG)
    methods = [OpenMDAO(), BevInProcess(config)]
    ros = None
    if args.ros:
        log_dir = Path("/tmp") / f"bench_sellar_{os.getpid()}"
        log_dir.mkdir(parents=True, exist_ok=True)
        ros = BevRos(config, args.domain_id, log_dir)
        methods.append(ros)
    try:
        runs: dict[str, list[dict]] = {m.name: [] for m in methods}
        for m in methods:
            m.once()  # untimed warm-up (imports, first discovery)
        for _ in range(args.repeat):
            for m in methods:
                runs[m.name].append(m.once())
    finally:
        if ros is not None:
            ros.close()
    out = {"bench": "bench_sellar", "host_cpus": os.cpu_count(), "repeat": args.repeat,
           "reference_objective": REF_F, "openmdao_version": methods[0].version, "methods": []}
    for m in methods:
        rs = runs[m.name]
        last = rs[-1]
        row = {"method": m.name, **_stats([r["wall_s"] for r in rs]),
               "objective": last["objective"], "objective_rel_error": abs(last["objective"] - REF_F) / REF_F,
               "design": last["design"], "iterations": last["iterations"],
               **{k: last[k] for k in ("mda_evaluations", "discipline_evaluations", "model_solves", "retried",
                                       "dropped") if k in last}}
        if "optimisation_s" in last:
            row["optimisation_only"] = _stats([r["optimisation_s"] for r in rs])
        out["methods"].append(row)
    om_med = out["methods"][0]["median_s"]
    for row in out["methods"]:
        row["ratio_to_openmdao"] = row["median_s"] / om_med
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2, default=float))
    print(f"Sellar MDF, {args.repeat} runs each (interleaved); reference f = {REF_F}")
    print(f"{'method':58s} {'median s':>9s} {'min':>8s} {'max':>8s} {'x OM':>6s} {'f':>12s} {'iter':>5s}")
    for row in out["methods"]:
        print(f"{row['method']:58s} {row['median_s']:9.4f} {row['min_s']:8.4f} {row['max_s']:8.4f} "
              f"{row['ratio_to_openmdao']:6.2f} {row['objective']:12.8f} {row['iterations']:5d}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
