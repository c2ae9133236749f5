"""Designs of experiments and a global Sobol' analysis on the BEV problem (config/leaf_nedc.yaml).

1. DOE designs/s: a Latin hypercube of --designs designs over the bounds, analysed as ONE batch
   (the MDA of ``bev-mdo sweep --doe``) in process and over ROS (the config's six discipline nodes,
   started once for the bench on --domain-id, localhost-only, signed as a command's own nodes are; their
   start-up is not timed). Each run draws a new hypercube (seed = run number).
2. A Sobol' analysis with N = 1,024 (``bev-mdo sensitivity --global sobol --samples 1024``: N (D + 2)
   = 5,120 designs in one batch, then SALib's estimates with 1,000 bootstrap resamples for the four
   outputs): its whole cost, and the evaluation alone, in process and over ROS.

Transports are interleaved round by round (the host is noisy); median, min and max of --repeat runs.

    flock /tmp/bev_ros_tests.lock .venv/bin/python bench/bench_doe.py --repeat 5 --domain-id 217 [--no-ros]
"""
from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "bench"))

import _results  # noqa: E402

from bev_mdo.api.doe import sample  # noqa: E402
from bev_mdo.api.sensitivity import analyse  # noqa: E402
from bev_mdo.api.sensitivity import build_batch  # noqa: E402
from bev_mdo.config import load_config, resolve_disciplines, run_settings  # noqa: E402
from bev_mdo.mdo.driver import _mda  # noqa: E402
from bev_mdo.mdo.evaluator import InProcessEvaluator  # noqa: E402
from bev_mdo.mdo.problem import Problem  # noqa: E402

CONFIG = REPO / "config" / "leaf_nedc.yaml"


def _doe_rate(config, evaluator, problem, n: int, seed: int) -> float:
    bounds = {d.name: (d.lower, d.upper) for d in problem.design_variables}
    mda = _mda(run_settings(config), evaluator, problem)
    cols = sample("lhs", bounds, n, seed)
    t = time.perf_counter()
    res = mda.run(cols)
    dt = time.perf_counter() - t
    assert res.ok.all(), "a design failed"
    return n / dt


def _sobol_cost(config, evaluator, defaults, seed: int) -> tuple[float, float]:
    fun, point, bounds, outputs, problem = build_batch(config, evaluator, defaults)
    spent = []

    def timed(X):
        t = time.perf_counter()
        out = fun(X)
        spent.append(time.perf_counter() - t)
        return out

    t = time.perf_counter()
    analyse("sobol", timed, point, bounds, list(problem.names), outputs, 1024, seed, design=list(problem.names))
    return time.perf_counter() - t, spent[0]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--designs", type=int, default=1024)
    ap.add_argument("--domain-id", type=int, default=217)
    ap.add_argument("--no-ros", action="store_true")
    args = ap.parse_args()
    config = load_config(CONFIG)
    problem = Problem.from_config(config["problem"])
    local = InProcessEvaluator(resolve_disciplines(config))
    defaults = {k: v for s in local.specs.values() for k, v in s.parameters.items()}
    transports = {"inprocess": (local, None)}
    stack = contextlib.ExitStack()  # the ROS evaluator's nodes, stopped at the end
    if not args.no_ros:
        from bev_mdo.api.transport import Evaluating

        ns = argparse.Namespace(domain_id=args.domain_id, discovery=None, static_peers=None, discovery_server=None)
        transports["ros"] = (stack.enter_context(Evaluating(config, ns, node_name="bench_doe")), defaults)
    runs = {k: {"doe": [], "sobol": [], "sobol_eval": []} for k in transports}
    try:
        for name, (ev, d) in transports.items():  # untimed warm-up: first discovery, imports
            _doe_rate(config, ev, problem, 64, 0)
        for r in range(args.repeat):
            for name, (ev, d) in transports.items():
                runs[name]["doe"].append(_doe_rate(config, ev, problem, args.designs, r + 1))
                total, evaluation = _sobol_cost(config, ev, d, r + 1)
                runs[name]["sobol"].append(total)
                runs[name]["sobol_eval"].append(evaluation)
                print(f"round {r + 1} {name}: {runs[name]['doe'][-1]:.0f} designs/s, Sobol' N=1024 "
                      f"{total:.2f} s ({evaluation:.2f} s evaluating)", flush=True)
    finally:
        stack.close()
    figures = []
    for name in transports:
        where = "in process" if name == "inprocess" else "over ROS (6 discipline nodes, started before timing)"
        figures += [
            _results.figure(f"DOE: Latin hypercube of {args.designs} BEV designs as one batch, {where}", "designs/s",
                            runs[name]["doe"]),
            _results.figure(f"Sobol' analysis N = 1,024 on the BEV problem (5,120 designs, SALib, 4 outputs), {where}: "
                            "whole cost", "s", runs[name]["sobol"]),
            _results.figure(f"Sobol' analysis N = 1,024 on the BEV problem, {where}: the evaluation of its 5,120 "
                            "designs alone", "s", runs[name]["sobol_eval"]),
        ]
    _results.write("doe", figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
