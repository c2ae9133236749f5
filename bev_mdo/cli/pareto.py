"""``bev-mdo pareto CONFIG [--topology T | --all-topologies] [--transport inprocess|ros [--instances N|NAME=N]]
[--generations G --pop P --seed S] [--objectives a,b,c] [--out DIR]``.

Thesis §4.4 (eqs 4-6..4-10): NSGA-II (pymoo) over the config's MDA, minimising energy on the
combined Artemis cycle, 0-100 km/h time and powertrain cost subject to the problem's
constraints (NEDC range >= 175 km, cycle torque/speed feasibility). Every generation is ONE
batch of the whole population through the evaluator (in-process, or the discipline nodes over
ROS). ``--topology`` / ``--all-topologies`` rewrite ``vehicle.topology`` (and the ``topology``
option of any discipline that sets one) and the design variables (``TOPOLOGY_BOUNDS`` of
bev_mdo.studies.topologies, which holds the study itself: benchmark, picks, plots; the
battery keeps the config's bounds). Writes into ``--out`` (default ``bags/<name>_pareto_<time>/``):

* ``bag/``: a rosbag2 MCAP bag with one ParetoFront per generation per topology on
  /bev_mdo/pareto_front (``final`` on the last; ``read_fronts`` reads them back). Over ROS the
  recorder node writes it, with every request and result of the run; in process the fronts
  are written directly;
* ``pareto_<TOPOLOGY>.csv``: the feasible non-dominated designs, every MDA variable;
* ``benchmark.csv``: the 80 kW benchmark of Table 4-4 evaluated per topology beside Table 4-5;
* ``fig_4_5_energy_accel.png``, ``fig_4_6_energy_cost.png`` (like Figs 4-5, 4-6);
* ``summary.json``: timings, evaluations, the Table 4-6 / 4-7 style picks.
"""
from __future__ import annotations

import json
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from bev_mdo.studies import topologies as study

OBJECTIVES = ("energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd")


def register(subparsers) -> None:
    p = subparsers.add_parser("pareto", help="NSGA-II Pareto fronts of powertrain topologies (thesis ch.4)")
    p.add_argument("config", help="run config YAML (e.g. config/topologies_artemis.yaml)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--topology", default=None, help="SM-SA, DM-DA, IWM-SA or IWM-DA (default: the config's)")
    g.add_argument("--all-topologies", action="store_true", help="run all four topologies")
    p.add_argument("--transport", choices=("inprocess", "ros"), default="inprocess")
    p.add_argument("--generations", type=int, default=30)
    p.add_argument("--pop", type=int, default=100, help="population size (one batch per generation)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--objectives", default=",".join(OBJECTIVES), metavar="A,B,C")
    p.add_argument("--out", default=None, help="output (bag) directory, default bags/<name>_pareto_<time>")
    p.add_argument("--domain-id", type=int, default=None, help="ROS domain id (default: the config's)")
    p.add_argument("--instances", default=None, metavar="N|NAME=N,...",
                   help="ROS: run N instances of every discipline, or of the named ones (a pool: they share "
                        "each population, as for optimize; docs/scaling.md)")
    p.add_argument("--no-plots", action="store_true")
    from bev_mdo.cli.overrides import add_override_arguments

    add_override_arguments(p)
    p.set_defaults(func=run)


def _read_raw(path):
    import yaml

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{path}: no such config file")
    raw = yaml.safe_load(p.read_text())
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: the config must be a YAML mapping")
    return raw


def run(args) -> int:
    from bev_mdo.config import load_config
    from bev_mdo.models.topology import TOPOLOGIES, get_topology

    raw = _read_raw(args.config)
    if args.generations < 1 or args.pop < 4:
        raise ValueError(f"--generations must be >= 1 and --pop >= 4, got {args.generations}, {args.pop}")
    stamp = time.strftime("%Y%m%d_%H%M%S")
    out = Path(args.out) if args.out else Path("bags") / f"{raw.get('name', 'run')}_pareto_{stamp}"
    bag = out / "bag"
    if bag.exists():
        raise ValueError(f"{bag} already exists; choose another --out")
    from bev_mdo.cli import overrides

    if overrides.given(args):  # the command line's overrides, checked against the config as written
        raw = overrides.apply(raw, args, overrides.known_names(load_config(args.config)))
    load_config(args.config, edit=lambda _: raw)  # validates the config (bad topology/variable: exit 2)
    if getattr(args, "instances", None) and args.transport != "ros":
        raise ValueError("--instances needs --transport ros (pools of discipline nodes)")
    objectives = [o.strip() for o in args.objectives.split(",") if o.strip()]
    topologies = list(TOPOLOGIES) if args.all_topologies else [
        get_topology(args.topology).name if args.topology else study.config_topology(raw)]
    configs = {t: load_config(study.config_for_topology(raw, t)) for t in topologies}
    out.mkdir(parents=True, exist_ok=True)
    run_id = uuid.uuid4().hex[:16]
    results, bench, timing = {}, {}, {}
    from bev_mdo import sessions

    if args.transport == "ros":
        from bev_mdo.cli.ros_args import ros_section
        from bev_mdo.config import discipline_names
        from bev_mdo.ros.launch import parse_instances

        instances = parse_instances(args.instances, discipline_names(next(iter(configs.values()))))
        session = sessions.ParetoRosSession(raw, ros_section(raw, args), out, bag, run_id, instances=instances)
    else:
        session = sessions.ParetoInProcessSession(raw, bag, run_id)
    with session:
        for t, cfg in configs.items():
            print(f"{t}: NSGA-II {args.pop} x {args.generations} over {args.transport}", file=sys.stderr)

            def on_front(front, final, t=t):
                session.sink.publish(front_message(front, run_id=run_id, topology=t, final=final))

            with session.evaluator(cfg, t) as ev:
                res, b = _run_one(cfg, ev, objectives, args, t, on_front)
            results[t], bench[t] = res, b
            timing[t] = {"wall_time_s": res.wall_time_s, "evaluations": res.evaluations, "batches": res.batches,
                         "mean_generation_s": float(np.mean(res.generation_times_s)),
                         "evaluations_per_s": res.evaluations / max(res.wall_time_s, 1e-12)}
            study.write_front(out / f"pareto_{t}.csv", res)
    study.write_benchmark(out / "benchmark.csv", bench)
    warnings = study.torque_warnings(bench)
    for w in warnings:
        print(w, file=sys.stderr)
    picks = study.picks(results, bench)
    summary = {"config": str(args.config), "transport": args.transport, "run_id": run_id, "bag": str(bag),
               "objectives": objectives, "generations": args.generations, "pop": args.pop, "seed": args.seed,
               "timing": timing, "benchmark": bench, "picks": picks, "out": str(out), "warnings": warnings,
               **session.stats}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    pngs = []
    if not args.no_plots:
        cyc = (next(iter(configs.values())).get("cycle") or {})
        pngs = study.plots(out, results, bench, objectives, cyc.get("name", "") if isinstance(cyc, dict) else "")
    for t in topologies:
        r = results[t]
        print(f"{t}: {len(r.X)} non-dominated designs, {r.evaluations} evaluations in {r.batches} batches, "
              f"{timing[t]['wall_time_s']:.1f} s")
    what = ", ".join(p.name for p in pngs) if pngs else (
        "no plots: --no-plots" if args.no_plots else "no plots: one objective has no trade-off to draw")
    print(f"wrote {out}/ (pareto_*.csv, benchmark.csv, summary.json, {what}, "
          f"bag/ with {session.sink.published} ParetoFront messages)")
    failed = session.stats.get("recorder_failed")  # known only once the session stopped its processes
    if failed:
        summary["recorder_failed"] = failed
        (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
        print(f"warning: {failed}", file=sys.stderr)
        return 3
    return 0


def front_message(front, **kw):
    """A ParetoFront message of one generation's front (see bev_mdo.ros.pareto_publisher)."""
    from bev_mdo.ros.pareto_publisher import front_message as make

    return make(front, **kw)


def _run_one(cfg, evaluator, objectives, args, topology, on_front=None):
    from bev_mdo.config import run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.pareto import run_nsga2

    form = build_formulation(run_settings(cfg), evaluator, "mdf")
    res = run_nsga2(form, objectives, pop_size=args.pop, generations=args.generations, seed=args.seed,
                    on_generation=lambda g, n, s: print(f"  gen {g}: {n} evaluations, {s:.2f} s", file=sys.stderr),
                    on_front=on_front)
    return res, study.benchmark(form, topology)
