"""Full MDF optimisation of the default problem, side by side in ONE run:

1. OpenMDAO in-process: an MDF Group (one ExplicitComponent per bev_mdo discipline, wrapping
   the very same discipline objects), NonlinearBlockGS, ScipyOptimizeDriver SLSQP, the same
   variable scaling (ref0=lower, ref=upper), constraints scaled like bev_mdo (ref=|bound|),
   totals by forward finite differences with the same step in scaled units as bev_mdo.
   (A second OpenMDAO row with the default NonlinearRunOnce is shown for information.)
2. bev_mdo in-process: ``run_optimization`` with ``InProcessEvaluator``.
3. Plain scipy SLSQP on the monolithic model (the discipline computes chained directly, no
   engine), same scaling, scipy's own forward differences (eps = the same scaled step).
4. bev_mdo over ROS (``--ros``, default when rclpy imports): six discipline node processes
   (domain --domain-id, default 60, localhost-only discovery), the coordinator in this process; the time is
   RunResult.wall_time_s (discovery excluded).

Startup is excluded everywhere: each method gets one untimed warm-up run, then ``--repeat``
timed runs of the optimisation call only; the median is reported. This is a bench: it prints
figures and asserts nothing about time.

    /work/main/.venv/bin/python bench/bench_openmdao.py [--repeat 5] [--no-ros] [--domain-id 60] [--json FILE]
    (optional: --profile FILE.pstats to cProfile the bev_mdo in-process runs)

OpenMDAO is a bench-only dependency: ``pip install -c constraints.txt -r bench/requirements.txt``.
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from bev_mdo.config import load_config, resolve_disciplines  # noqa: E402
from bev_mdo.mdo.driver import run_optimization  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.mdo.problem import Problem  # noqa: E402

CONFIG = REPO / "config" / "leaf_nedc.yaml"
ROS_DOMAIN = 60


# ----------------------------------------------------------------------------- common
class Setup:
    """What every method shares: the config, the discipline objects, the problem."""

    def __init__(self, config_path: Path):
        self.config_path = Path(config_path)
        self.config = load_config(str(config_path))
        self.disciplines = resolve_disciplines(self.config)
        self.problem = Problem.from_config(self.config["problem"])
        p = self.problem
        self.names = p.names
        self.lower, self.upper, self.scale = p.array("lower"), p.array("upper"), p.array("scale")
        self.x0 = p.x0()
        opt = self.config.get("optimizer", {})
        self.fd_step = float(opt.get("fd_step", 1e-6))        # in scaled units u = (x - lower) / scale
        if opt.get("fd_scheme", "forward") != "forward":
            raise SystemExit("bench: only the forward FD scheme is mirrored in OpenMDAO/scipy")
        self.slsqp = {"maxiter": 200, "ftol": 1e-10, **(opt.get("options") or {})}  # as bev_mdo.mdo.optimizers
        mda = self.config.get("mda", {})
        self.mda_tol = float(mda.get("tolerance", 1e-10))
        self.mda_maxiter = int(mda.get("max_iterations", 100))
        self.order = _chain_order(self.disciplines, set(self.names) | set(p.parameters))
        if p.parameters:
            raise SystemExit("bench: problem.parameters overrides are not mirrored here")


def _chain_order(disciplines, given: set[str]) -> list:
    """Feed-forward execution order (computed once; the monolithic model just calls in this order)."""
    have, order, todo = set(given), [], list(disciplines)
    while todo:
        ready = [d for d in todo if set(d.inputs) <= have]
        if not ready:
            raise SystemExit(f"bench: the monolithic model needs a feed-forward graph; stuck at "
                             f"{[d.name for d in todo]}")
        for d in ready:
            order.append(d)
            have |= set(d.outputs)
            todo.remove(d)
    return order


def _median(ts):
    return float(statistics.median(ts))


def _timed(fn, repeat: int):
    """One untimed warm-up, then `repeat` timed calls: (last result, list of seconds)."""
    fn()
    times, res = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
    return res, times


# ----------------------------------------------------------------------------- 1. OpenMDAO
def build_openmdao(s: Setup, nlbgs: bool = True):
    import openmdao.api as om
    from openmdao.approximation_schemes.finite_difference import FiniteDifference

    counts = {"component_runs": 0, "model_solves": 0}

    class DisciplineComp(om.ExplicitComponent):
        """One bev_mdo discipline object as an OpenMDAO component (same compute, same physics)."""

        def initialize(self):
            self.options.declare("disc", recordable=False)

        def setup(self):
            d = self.options["disc"]
            for v in d.inputs:
                self.add_input(v, val=1.0)
            for v in d.outputs:
                self.add_output(v, val=1.0)

        def compute(self, inputs, outputs):
            d = self.options["disc"]
            if d is s.order[0]:
                counts["component_runs"] += 1
            out = d.compute({v: inputs[v] for v in d.inputs})
            for v in d.outputs:
                outputs[v] = out[v]

    # approx_totals takes ONE absolute step applied to the unscaled variables; bev_mdo steps
    # fd_step in u = (x - lower) / scale, i.e. fd_step * scale_j in x_j. This FD scheme gives
    # each design variable its own physical step so both step the same points.
    phys_step = {f"dvs.{n}": s.fd_step * sc for n, sc in zip(s.names, s.scale)}

    class ScaledStepFD(FiniteDifference):
        def add_approximation(self, wrt, system, kwargs, vector=None):
            kwargs = dict(kwargs)
            if wrt in phys_step:
                kwargs["step"], kwargs["step_calc"] = phys_step[wrt], "abs"
            return super().add_approximation(wrt, system, kwargs, vector)

    class MDFGroup(om.Group):
        def _get_approx_scheme(self, method):
            if method == "fd" and "fd" not in self._approx_schemes:
                self._approx_schemes["fd"] = ScaledStepFD()
            return super()._get_approx_scheme(method)

        def _solve_nonlinear(self):
            counts["model_solves"] += 1
            return super()._solve_nonlinear()

    prob = om.Problem(MDFGroup(), reports=False)
    model = prob.model
    ivc = om.IndepVarComp()
    for n, x in zip(s.names, s.x0):
        ivc.add_output(n, val=float(x))
    model.add_subsystem("dvs", ivc, promotes=["*"])
    for d in s.disciplines:
        model.add_subsystem(d.name, DisciplineComp(disc=d), promotes=["*"])
    if nlbgs:
        model.nonlinear_solver = om.NonlinearBlockGS(maxiter=s.mda_maxiter, atol=s.mda_tol, rtol=s.mda_tol,
                                                     iprint=-1)
        model.linear_solver = om.LinearBlockGS(maxiter=s.mda_maxiter, atol=s.mda_tol, rtol=s.mda_tol, iprint=-1)
    for n, lo, hi in zip(s.names, s.lower, s.upper):
        model.add_design_var(n, lower=float(lo), upper=float(hi), ref0=float(lo), ref=float(hi))
    model.add_objective(s.problem.objective, ref=s.problem.objective_scale)
    for c in s.problem.constraints:
        if c.monitor:
            continue
        for kind, bound, scale in c.rows():  # bev_mdo: g = (bound - y) / scale, i.e. y / scale vs bound / scale
            model.add_constraint(c.name, **{kind: bound}, ref=scale)
    model.approx_totals(method="fd", step=s.fd_step, form="forward", step_calc="abs")
    prob.driver = om.ScipyOptimizeDriver(optimizer="SLSQP", tol=s.slsqp["ftol"], maxiter=s.slsqp["maxiter"],
                                         disp=False)
    prob.setup(check=False)
    prob.final_setup()
    return prob, counts


def run_openmdao(s: Setup, nlbgs: bool = True) -> dict:
    import openmdao

    def once():
        prob, counts = build_openmdao(s, nlbgs)     # startup: not timed
        t0 = time.perf_counter()
        prob.run_driver()
        wall = time.perf_counter() - t0
        res = getattr(prob.driver, "_scipy_optimize_result", None)  # scipy's OptimizeResult
        out = {
            "design": {n: float(prob.get_val(n)[0]) for n in s.names},
            "objective": float(prob.get_val(s.problem.objective)[0]),
            "iterations": int(getattr(res, "nit", 0) or 0) if res is not None else None,
            "evaluations": counts["model_solves"],
            "component_runs_per_discipline": counts["component_runs"],
            "driver_iter_count": int(prob.driver.iter_count),
            "success": bool(res.success) if res is not None else None,
            "wall_s": wall,
        }
        prob.cleanup()
        return out

    once()                                           # warm-up
    runs = [once() for _ in range(REPEAT)]
    last = runs[-1]
    label = "OpenMDAO in-process (NLBGS)" if nlbgs else "OpenMDAO in-process (RunOnce, info)"
    return {"method": label, **{k: v for k, v in last.items() if k != "wall_s"},
            "times_s": [r["wall_s"] for r in runs], "median_s": _median([r["wall_s"] for r in runs]),
            "min_s": min(r["wall_s"] for r in runs),
            "evaluations_note": "model nonlinear solves (driver + FD); each NLBGS solve runs every component "
                                "per sweep" if nlbgs else "model nonlinear solves (driver + FD)",
            "version": openmdao.__version__}


# ----------------------------------------------------------------------------- 2. bev_mdo in-process
def run_bev_inprocess(s: Setup, profile: str | None = None) -> dict:
    box = {}

    def once():
        ev = InProcessEvaluator(s.disciplines)
        r = run_optimization(s.config, ev)
        box["r"], box["waves"] = r, ev.waves
        return r

    if profile:
        import cProfile
        once()
        pr = cProfile.Profile()
        pr.enable()
        for _ in range(50):
            once()
        pr.disable()
        pr.dump_stats(profile)
    r, times = _timed(once, REPEAT)
    return {"method": "bev_mdo in-process", "design": r.design, "objective": r.objective,
            "iterations": r.iterations, "evaluations": r.mda_evaluations, "success": r.success,
            "batches": r.batches, "gradients": r.gradients, "waves": box["waves"],
            "wall_time_s_reported": r.wall_time_s,
            "times_s": times, "median_s": _median(times), "min_s": min(times),
            "evaluations_note": "RunResult.mda_evaluations (MDA points, as the driver counts them)"}


# ----------------------------------------------------------------------------- 3. plain scipy
def run_plain_scipy(s: Setup) -> dict:
    from scipy.optimize import Bounds, minimize

    rows = [(c.name, kind, bound, scale) for c in s.problem.constraints for kind, bound, scale in c.rows()]
    obj = s.problem.objective
    lower, scale, names, order = s.lower, s.scale, s.names, s.order
    box = {}

    def once():
        cache: dict[bytes, tuple[float, np.ndarray]] = {}
        nfev = [0]

        def model(u):                                 # the monolithic model: disciplines chained by hand
            key = u.tobytes()
            hit = cache.get(key)
            if hit is not None:
                return hit
            nfev[0] += 1
            x = lower + scale * u
            v = {n: np.array([xi]) for n, xi in zip(names, x)}
            for d in order:
                v.update(d.compute(v))
            c = np.array([(v[n][0] - b) / sc if k == "lower" else (b - v[n][0]) / sc for n, k, b, sc in rows])
            hit = cache[key] = (float(v[obj][0]), c)
            return hit

        res = minimize(lambda u: model(u)[0] / s.problem.objective_scale, (s.x0 - lower) / scale, method="SLSQP",
                       bounds=Bounds(np.zeros(len(names)), (s.upper - lower) / scale),
                       constraints=[{"type": "ineq", "fun": lambda u: model(u)[1]}],
                       options={"maxiter": s.slsqp["maxiter"], "ftol": s.slsqp["ftol"], "eps": s.fd_step})
        box["nfev"] = nfev[0]
        return res

    res, times = _timed(once, REPEAT)
    x = lower + scale * res.x
    v = {n: np.array([xi]) for n, xi in zip(names, x)}
    for d in order:
        v.update(d.compute(v))
    return {"method": "plain scipy SLSQP (monolithic)", "design": dict(zip(names, map(float, x))),
            "objective": float(v[obj][0]), "iterations": int(res.nit), "evaluations": box["nfev"],
            "success": bool(res.success), "times_s": times, "median_s": _median(times), "min_s": min(times),
            "evaluations_note": "model evaluations (memoised by u, so fun/constraint FD share points)"}


# ----------------------------------------------------------------------------- 4. bev_mdo over ROS
def run_bev_ros(s: Setup, log_dir: Path) -> dict:
    # network hygiene first: this process's own rclpy reads these at init
    for k in ("ROS_LOCALHOST_ONLY", "ROS_STATIC_PEERS", "ROS_DISCOVERY_SERVER"):
        os.environ.pop(k, None)
    os.environ["ROS_DOMAIN_ID"] = str(ROS_DOMAIN)
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    import rclpy

    from bev_mdo.ros import coordinator_node
    from bev_mdo.launcher import Launcher
    from bev_mdo.processes import discipline_argv
    from bev_mdo.testing import ros_env

    env = ros_env(ROS_DOMAIN)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST" and env["ROS_DOMAIN_ID"] == str(ROS_DOMAIN)
    launcher = Launcher(env, log_dir=log_dir)
    ctx = rclpy.context.Context()
    try:
        for d in s.disciplines:
            launcher.add(d.name, discipline_argv(d.name, str(s.config_path)))
        launcher.supervise()
        rclpy.init(context=ctx)
        runs = []
        for i in range(REPEAT + 1):                  # first run: warm-up (discovery, first messages)
            t0 = time.perf_counter()
            r, stats = coordinator_node.run(s.config, context=ctx)
            total = time.perf_counter() - t0
            if i:
                runs.append((r, stats, total))
        r, stats, _ = runs[-1]
        times = [x[0].wall_time_s for x in runs]
        restarts = {n.label: n.restarts for n in launcher.nodes if n.restarts}
        return {"method": "bev_mdo over ROS (6 node processes)", "design": r.design, "objective": r.objective,
                "iterations": r.iterations, "evaluations": r.mda_evaluations, "success": r.success,
                "batches": r.batches, "gradients": r.gradients,
                "times_s": times, "median_s": _median(times), "min_s": min(times),
                "incl_discovery_median_s": _median([x[2] for x in runs]),
                "dropped": stats["dropped"], "retried": stats["retried"], "node_restarts": restarts,
                "evaluations_note": "RunResult.mda_evaluations; time = RunResult.wall_time_s (discovery excluded)"}
    finally:
        if ctx.ok():
            rclpy.shutdown(context=ctx)
        launcher.stop()


# ----------------------------------------------------------------------------- report
def _fmt_design(d: dict) -> str:
    return ", ".join(f"{v:.6g}" for v in d.values())


def main(argv=None) -> int:
    global REPEAT, ROS_DOMAIN
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", default=str(CONFIG))
    ap.add_argument("--repeat", type=int, default=11)
    try:
        import rclpy  # noqa: F401
        have_ros = True
    except ImportError:
        have_ros = False
    ap.add_argument("--ros", dest="ros", action="store_true", default=have_ros,
                    help="also run bev_mdo over ROS (default: on when rclpy imports)")
    ap.add_argument("--no-ros", dest="ros", action="store_false")
    ap.add_argument("--domain-id", type=int, default=ROS_DOMAIN, help=f"ROS domain (default {ROS_DOMAIN})")
    ap.add_argument("--json", help="results file (default bench/results/openmdao.json)")
    ap.add_argument("--profile", help="cProfile 50 bev_mdo in-process runs into this .pstats file")
    ap.add_argument("--log-dir", default=None, help="node logs (default: a temp dir)")
    args = ap.parse_args(argv)
    REPEAT = max(1, args.repeat)
    ROS_DOMAIN = args.domain_id

    s = Setup(Path(args.config))
    results = [run_openmdao(s, nlbgs=True), run_bev_inprocess(s, args.profile), run_plain_scipy(s),
               run_openmdao(s, nlbgs=False)]
    if args.ros:
        import tempfile
        log_dir = Path(args.log_dir) if args.log_dir else Path(tempfile.mkdtemp(prefix="bench_openmdao_"))
        results.insert(2, run_bev_ros(s, log_dir))
    ref = results[0]
    ref_x = np.array(list(ref["design"].values()))
    for r in results:
        x = np.array(list(r["design"].values()))
        r["rel_diff_design_vs_openmdao"] = dict(zip(s.names, map(float, np.abs(x - ref_x) / np.abs(ref_x))))
        r["rel_diff_objective_vs_openmdao"] = abs(r["objective"] - ref["objective"]) / abs(ref["objective"])
        r["ratio_to_openmdao"] = r["median_s"] / ref["median_s"]

    by = {r["method"]: r for r in results}
    bev, plain = by["bev_mdo in-process"], by["plain scipy SLSQP (monolithic)"]
    summary = {"ratio_bev_inprocess_to_plain_scipy": bev["median_s"] / plain["median_s"],
               "target_bev_inprocess_to_plain_scipy": 1.2,
               "target_ros_to_openmdao": 1.0}
    ros = next((r for r in results if r["method"].startswith("bev_mdo over ROS")), None)
    if ros:
        summary["ratio_ros_to_openmdao"] = ros["ratio_to_openmdao"]

    print(f"\nFull MDF optimisation of {s.config_path.name} ({s.config['name']}); design = "
          f"({', '.join(s.names)}); median of {REPEAT} timed runs after one warm-up, startup excluded\n")
    hdr = f"{'method':38s} {'optimum design':30s} {'objective':>12s} {'iter':>5s} {'evals':>6s} " \
          f"{'median ms':>10s} {'min ms':>7s} {'x OpenMDAO':>10s}"
    print(hdr)
    print("-" * len(hdr))
    for r in results:
        print(f"{r['method']:38s} {_fmt_design(r['design']):30s} {r['objective']:12.8g} "
              f"{str(r['iterations']):>5s} {r['evaluations']:6d} {r['median_s'] * 1e3:10.2f} {r['min_s'] * 1e3:7.2f} "
              f"{r['ratio_to_openmdao']:10.3f}")
    print("\nrelative difference of each optimum to OpenMDAO's (|x - x_om| / |x_om| per variable; objective):")
    for r in results[1:]:
        d = r["rel_diff_design_vs_openmdao"]
        print(f"  {r['method']:38s} " + "  ".join(f"{k} {v:.2e}" for k, v in d.items())
              + f"  objective {r['rel_diff_objective_vs_openmdao']:.2e}")
    print("\nevaluations: " + "; ".join(f"{r['method']}: {r['evaluations_note']}" for r in results[:3]))
    print(f"OpenMDAO NLBGS component runs per discipline over the last run: "
          f"{ref['component_runs_per_discipline']} (for {ref['evaluations']} model solves)")
    print(f"\nbev_mdo in-process / plain scipy: {summary['ratio_bev_inprocess_to_plain_scipy']:.3f} "
          f"(target <= 1.2; ratio of the minima {bev['min_s'] / plain['min_s']:.3f})")
    if ros:
        print(f"bev_mdo over ROS / OpenMDAO in-process: {summary['ratio_ros_to_openmdao']:.3f} (target <= 1.0; "
              f"ratio of the minima {ros['min_s'] / ref['min_s']:.3f}); "
              f"with discovery: {ros['incl_discovery_median_s'] * 1e3:.1f} ms median; dropped {ros['dropped']}, "
              f"retried {ros['retried']}, node restarts {ros['node_restarts'] or 0}")
    print(f"OpenMDAO {ref['version']}; host load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs "
          f"(timings are noisy on a shared host: compare the min column too)")
    summary["loadavg_1min"], summary["cpus"] = os.getloadavg()[0], os.cpu_count()
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import _results

    figs = [_results.figure(f"full MDF optimisation of the default problem: {r['method']} (one run each, {REPEAT} runs)",
                            "ms", [t * 1e3 for t in r["times_s"]]) for r in results if r.get("times_s")]
    figs.append(_results.figure("bev_mdo in process / plain scipy SLSQP (ratio of medians)", "–",
                                [summary["ratio_bev_inprocess_to_plain_scipy"]], "<= 1.2"))
    if ros:
        figs.append(_results.figure("bev_mdo over ROS / OpenMDAO in process (ratio of medians)", "–",
                                    [summary["ratio_ros_to_openmdao"]], "<= 1.0"))
    _results.write("openmdao", figs, path=args.json,
                   extra={"config": str(s.config_path), "repeat": REPEAT, "results": results, "summary": summary})
    return 0


REPEAT = 11

if __name__ == "__main__":
    sys.exit(main())
