"""Sellar MDF, side by side in ONE run, methods interleaved round by round:

1. OpenMDAO's own Sellar MDF in process: ``openmdao.test_suite.components.sellar_feature.SellarMDA``
   (cycle group with NonlinearBlockGS, discipline partials by FD, ExecComp objective/constraints),
   ``ScipyOptimizeDriver(optimizer="SLSQP", tol=1e-8)``, z in [-10, 10] x [0, 10], x in [0, 10],
   con1 = 3.16 - y1 <= 0, con2 = y2 - 24 <= 0, start z = (5, 2), x = 1 (the OpenMDAO docs' problem).
2. OpenMDAO with Newton: the same model built from OpenMDAO's ``SellarDis1withDerivatives`` /
   ``SellarDis2withDerivatives`` (analytic partials), the cycle solved by ``NewtonSolver
   (solve_subsystems=False)`` with a ``DirectSolver`` (OpenMDAO's default tolerances, 1e-10), the
   fair counterpart of bev_mdo's Newton MDA.
3. bev_mdo in process: ``examples/sellar/sellar_mdf.yaml`` (Gauss-Seidel) and
   ``sellar_mdf_newton.yaml`` (Newton-Raphson, tangent warm start; ``newton_cold``: the same with
   ``mda.warm_start: false``, every MDA from the guesses with a seeding call; ``newton_fused``: the
   example with ``mda.fuse_downstream: true``, the objective in every Newton step's wave)
   through ``run_optimization`` with ``InProcessEvaluator``
   (the user-discipline interface only; the example disciplines give analytic partials, so the MDF
   gradient is assembled from them: ``optimizer.derivatives: auto``).
4. bev_mdo over ROS: the same two configs, one node process per discipline (the same three nodes
   serve both: the MDA method is not part of a node's binding), domain --domain-id,
   localhost-only discovery, the coordinator in this process. Two times: the coordinator's ``run``
   call from its start to its result (handshake with the running nodes, warm-up, optimisation;
   node start-up excluded, it is in bench_sellar_startup.py), and the optimisation alone
   (``RunResult.wall_time_s``).

Counted per run (bench-side wrappers, nothing in bev_mdo changed): ``evaluate()`` calls = request
waves (in process: ``InProcessEvaluator.waves``; over ROS: calls of ``RosEvaluator.evaluate`` and the
requests they sent, i.e. one per discipline per call, and the time spent inside them, which gives the
time per round trip).

Each method gets one untimed warm-up run, then ``--repeat`` timed runs, interleaved round by round
(the host is noisy): median, min and max are reported, with the 1-minute load average before and
after. It prints and writes figures (bench/results/bench_sellar.json, rendered by
scripts/render_bench.py); it asserts nothing about time.

    flock /tmp/bev_bench.lock flock /tmp/bev_ros.lock .venv/bin/python bench/bench_sellar.py --repeat 7
        [--no-ros] [--domain-id 140]

OpenMDAO is a bench-only dependency: ``pip install -c constraints.txt -r bench/requirements.txt``.
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

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402

CONFIGS = {"gauss_seidel": REPO / "examples" / "sellar" / "sellar_mdf.yaml",
           "newton": REPO / "examples" / "sellar" / "sellar_mdf_newton.yaml",
           "newton_cold": REPO / "examples" / "sellar" / "sellar_mdf_newton.yaml",
           "newton_fused": REPO / "examples" / "sellar" / "sellar_mdf_newton.yaml"}
# newton_cold: the Newton example without warm start (every MDA from the coupling guesses with a
# seeding call); newton_fused: the example with the objective fused into the Newton steps' waves
OVERRIDES = {"newton_cold": {"warm_start": False, "fuse_downstream": False},
             "newton_fused": {"fuse_downstream": True}}


def _config(method: str) -> dict:
    config = load_config(CONFIGS[method])
    config["mda"].update(OVERRIDES.get(method, {}))
    return config
REF_F = 3.18339395


def _stats(times: list[float]) -> dict:
    return {"times_s": times, "median_s": statistics.median(times), "min_s": min(times), "max_s": max(times)}


class OpenMDAO:
    def __init__(self, solver: str = "nlbgs"):
        import openmdao.api as om
        from openmdao.test_suite.components.sellar import SellarDis1withDerivatives, SellarDis2withDerivatives
        from openmdao.test_suite.components.sellar_feature import SellarMDA

        self.om, self.solver = om, solver
        self.version = __import__("openmdao").__version__
        if solver == "nlbgs":
            self.name = "OpenMDAO SellarMDA (NonlinearBlockGS + SLSQP), in process"
            self.model = SellarMDA
            return
        self.name = "OpenMDAO Sellar, analytic partials (NewtonSolver + DirectSolver, SLSQP), in process"

        class SellarNewton(om.Group):
            def setup(self):
                cycle = self.add_subsystem("cycle", om.Group(), promotes=["*"])
                cycle.add_subsystem("d1", SellarDis1withDerivatives(), promotes_inputs=["x", "z", "y2"],
                                    promotes_outputs=["y1"])
                cycle.add_subsystem("d2", SellarDis2withDerivatives(), promotes_inputs=["z", "y1"],
                                    promotes_outputs=["y2"])
                self.set_input_defaults("x", 1.0)
                self.set_input_defaults("z", [5.0, 2.0])
                cycle.nonlinear_solver = om.NewtonSolver(solve_subsystems=False)
                cycle.linear_solver = om.DirectSolver()
                self.add_subsystem("obj_cmp", om.ExecComp("obj = x**2 + z[1] + y1 + exp(-y2)", z=[0.0, 0.0], x=0.0),
                                   promotes=["x", "z", "y1", "y2", "obj"])
                self.add_subsystem("con_cmp1", om.ExecComp("con1 = 3.16 - y1"), promotes=["con1", "y1"])
                self.add_subsystem("con_cmp2", om.ExecComp("con2 = y2 - 24.0"), promotes=["con2", "y2"])

        self.model = SellarNewton

    def once(self) -> dict:
        om = self.om
        t0 = time.perf_counter()
        prob = om.Problem(reports=False)
        prob.model = self.model()
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
        cycle = prob.model._get_subsystem("cycle")
        return {"wall_s": wall, "objective": float(prob.get_val("obj")[0]),
                "design": {"z1": float(z[0]), "z2": float(z[1]), "x": float(prob.get_val("x")[0])},
                "iterations": int(prob.driver.iter_count), "model_solves": int(prob.model.iter_count),
                "discipline_evaluations": {"d1": int(cycle._get_subsystem("d1").iter_count),
                                           "d2": int(cycle._get_subsystem("d2").iter_count)}}


class BevInProcess:
    def __init__(self, method: str):
        self.method, self.config = method, _config(method)
        self.name = f"bev_mdo in process, {method} MDA (examples/sellar)"

    def once(self) -> dict:
        t0 = time.perf_counter()
        ev = InProcessEvaluator(resolve_disciplines(self.config))
        r = run_optimization(self.config, ev)
        wall = time.perf_counter() - t0
        return {"wall_s": wall, "optimisation_s": r.wall_time_s, "objective": r.objective, "design": r.design,
                "iterations": r.iterations, "mda_evaluations": r.mda_evaluations,
                "discipline_evaluations": r.discipline_evaluations, "feasible": r.feasible,
                "evaluate_calls": ev.waves}


class RosNodes:
    """Three discipline node processes serving both configs, and an rclpy context; counts the waves."""

    def __init__(self, domain: int, log_dir: Path):
        import rclpy
        import yaml

        from bev_mdo.ros import evaluator as ros_evaluator
        from bev_mdo.launcher import Launcher
        from bev_mdo.processes import discipline_argv
        from bev_mdo.testing import ros_env

        env = ros_env(domain)
        assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
        for k in ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER"):
            os.environ.pop(k, None)
        os.environ.update({k: env[k] for k in ("ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE")})
        self.launcher = Launcher(env, log_dir=log_dir)
        config = load_config(CONFIGS["gauss_seidel"])
        cfg_path = log_dir / "config.yaml"
        cfg_path.write_text(yaml.safe_dump(config, sort_keys=False))
        for entry in config["disciplines"]:
            self.launcher.add(entry["name"], discipline_argv(entry["name"], str(cfg_path)))
        self.launcher.supervise()
        self.ctx = rclpy.context.Context()
        rclpy.init(context=self.ctx)
        # count evaluate() calls (request waves), requests and the time inside them (bench-side wrapper)
        self.counter = {"calls": 0, "requests": 0, "seconds": 0.0}
        cls = ros_evaluator.RosEvaluator
        original = cls.evaluate
        counter = self.counter

        def counted(ev, calls, *a, **kw):
            t0 = time.perf_counter()
            try:
                return original(ev, calls, *a, **kw)
            finally:
                counter["calls"] += 1
                counter["requests"] += len(calls)
                counter["seconds"] += time.perf_counter() - t0

        cls.evaluate = counted

    def close(self):
        import rclpy

        rclpy.shutdown(context=self.ctx)
        self.launcher.stop()


class BevRos:
    def __init__(self, method: str, nodes: RosNodes, domain: int):
        self.method, self.nodes = method, nodes
        self.config = _config(method)
        self.config["ros"]["domain_id"] = domain
        self.name = f"bev_mdo over ROS, {method} MDA (3 node processes, coordinator here)"

    def once(self) -> dict:
        from bev_mdo.ros import coordinator_node

        c = self.nodes.counter
        c.update(calls=0, requests=0, seconds=0.0)
        t0 = time.perf_counter()
        r, stats = coordinator_node.run(self.config, context=self.nodes.ctx)
        wall = time.perf_counter() - t0
        return {"wall_s": wall, "optimisation_s": r.wall_time_s, "objective": r.objective, "design": r.design,
                "iterations": r.iterations, "mda_evaluations": r.mda_evaluations,
                "discipline_evaluations": r.discipline_evaluations, "feasible": r.feasible,
                "evaluate_calls": c["calls"], "requests": c["requests"], "evaluate_s": c["seconds"],
                "retried": stats["retried"], "dropped": stats["dropped"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--no-ros", dest="ros", action="store_false")
    ap.add_argument("--domain-id", type=int, default=140)
    ap.add_argument("--json", default=str(REPO / "bench" / "results" / "bench_sellar.json"))
    args = ap.parse_args(argv)
    load_before = os.getloadavg()
    variants = ("gauss_seidel", "newton_cold", "newton", "newton_fused")
    methods = [OpenMDAO("nlbgs"), OpenMDAO("newton"), *(BevInProcess(m) for m in variants)]
    nodes = None
    if args.ros:
        log_dir = Path("/tmp") / f"bench_sellar_{os.getpid()}"
        log_dir.mkdir(parents=True, exist_ok=True)
        nodes = RosNodes(args.domain_id, log_dir)
        methods += [BevRos(m, nodes, args.domain_id) for m in variants]
    try:
        runs = _results.interleaved(methods, args.repeat)
    finally:
        if nodes is not None:
            nodes.close()
    load_after = os.getloadavg()
    rows = []
    for m in methods:
        rs = runs[m.name]
        last = rs[-1]
        row = {"method": m.name, **_stats([r["wall_s"] for r in rs]),
               "objective": last["objective"], "objective_rel_error": abs(last["objective"] - REF_F) / REF_F,
               "design": last["design"], "iterations": last["iterations"],
               **{k: last[k] for k in ("mda_evaluations", "discipline_evaluations", "model_solves", "retried",
                                       "dropped", "evaluate_calls", "requests") if last.get(k) is not None}}
        if "optimisation_s" in last:
            row["optimisation_only"] = _stats([r["optimisation_s"] for r in rs])
        if "evaluate_s" in last:
            row["evaluate_only"] = _stats([r["evaluate_s"] for r in rs])
            row["seconds_per_evaluate_call"] = _stats([r["evaluate_s"] / r["evaluate_calls"] for r in rs])
        rows.append(row)
    om_med = rows[0]["median_s"]
    for row in rows:
        row["ratio_to_openmdao"] = row["median_s"] / om_med
    figures = []
    for m, row in zip(methods, rows):
        figures.append(_results.figure(f"{row['method']}: start to result", "s", row["times_s"]))
        if isinstance(m, BevRos):
            figures.append(_results.figure(f"{row['method']}: optimisation only (RunResult.wall_time_s)", "s",
                                           row["optimisation_only"]["times_s"],
                                           target="<= OpenMDAO NonlinearBlockGS in process"))
            figures.append(_results.figure(f"{row['method']}: time per request wave (evaluate call), "
                                           f"{row['evaluate_calls']} waves / {row['requests']} requests per run",
                                           "ms", [1e3 * t for t in row["seconds_per_evaluate_call"]["times_s"]]))
    extra = {"repeat": args.repeat, "reference_objective": REF_F, "openmdao_version": methods[0].version,
             "load_average_before": [round(v, 2) for v in load_before],
             "load_average_after": [round(v, 2) for v in load_after], "methods": rows}
    _results.write("bench_sellar", figures, path=args.json, extra=extra)
    print(f"Sellar MDF, {args.repeat} runs each (interleaved); reference f = {REF_F}; "
          f"load {load_before[0]:.2f} -> {load_after[0]:.2f}")
    print(f"{'method':88s} {'median s':>9s} {'min':>8s} {'max':>8s} {'x OM':>6s} {'opt. s':>8s} {'calls':>6s} "
          f"{'f':>12s} {'iter':>5s}")
    for row in rows:
        opt = row.get("optimisation_only", {}).get("median_s")
        print(f"{row['method']:88s} {row['median_s']:9.4f} {row['min_s']:8.4f} {row['max_s']:8.4f} "
              f"{row['ratio_to_openmdao']:6.2f} {'' if opt is None else f'{opt:8.4f}':>8s} "
              f"{row.get('evaluate_calls', ''):>6} {row['objective']:12.8f} {row['iterations']:5d}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
