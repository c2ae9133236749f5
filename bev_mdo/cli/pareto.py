"""``bev-mdo pareto CONFIG [--objectives A,B[,...]] [--transport inprocess|ros [--instances N|NAME=N]]
[--generations G --pop P --seed S] [--out DIR] [--topology T | --all-topologies]``.

NSGA-II (pymoo, mdo/pareto.py) over the config's MDA for any problem with two or more objectives:
the config's ``problem.objectives`` (each an output name, minimised, or ``{name, maximize: true}``),
or ``--objectives a,b`` (minimised). The problem's constraints are pymoo's inequality constraints;
every generation is ONE batch of the whole population through the evaluator the other commands use
(in process, or the discipline nodes over ROS). Writes into ``--out`` (default
``bags/<name>_pareto_<time>/``):

* ``bag/``: a rosbag2 MCAP bag with one ParetoFront per generation on /bev_mdo/pareto_front (``final``
  on the last). Over ROS the recorder node writes it, with every request and result of the run; in
  process the fronts are written directly;
* ``front.csv``: the feasible non-dominated designs, every MDA variable; ``front.json``: the same
  designs, the objectives and the run's figures; ``front_<b>_vs_<a>.png``: one plot per pair.

``--topology T`` / ``--all-topologies``: the thesis' chapter-4 topology study of the BEV problem
(§4.4; bev_mdo.studies.topologies), per topology: ``pareto_<T>.csv``, ``benchmark.csv`` (Table 4-4
design beside Table 4-5), ``fig_4_5_energy_accel.png``, ``fig_4_6_energy_cost.png``, ``summary.json``.
"""
from __future__ import annotations

import csv
import json
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from bev_mdo.studies import topologies as study

OBJECTIVES = study.OBJECTIVES  # the study's default (energy, 0-100 km/h time, cost)


def register(subparsers) -> None:
    from bev_mdo.cli import SUBCOMMANDS

    p = subparsers.add_parser("pareto", help=SUBCOMMANDS["pareto"][1])
    p.add_argument("config", help="run config YAML (e.g. examples/pareto/srn.yaml, config/topologies_artemis.yaml)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--topology", default=None, help="topology study: SM-SA, DM-DA, IWM-SA or IWM-DA (BEV problem)")
    g.add_argument("--all-topologies", action="store_true", help="topology study: all four topologies")
    p.add_argument("--transport", choices=("inprocess", "ros"), default="inprocess")
    p.add_argument("--generations", type=int, default=30)
    p.add_argument("--pop", type=int, default=100, help="population size (one batch per generation)")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--objectives", default=None, metavar="A,B[,C]",
                   help="outputs to minimise (default: the config's problem.objectives)")
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
    from bev_mdo.config import check_run_name
    from bev_mdo.yamlload import read_yaml_file

    p = Path(path)
    if not p.is_file():
        raise ValueError(f"{path}: no such config file")
    raw = read_yaml_file(p)
    if not isinstance(raw, dict):
        raise ValueError(f"{path}: the config must be a YAML mapping")
    try:
        check_run_name(raw.get("name", "run"))  # names the output folder: checked before anything is made
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return raw


def _objectives(args, cfg) -> list[tuple[str, bool]]:
    """(name, maximize) of the objectives: ``--objectives`` (minimised), else the config's."""
    from bev_mdo.mdo.problem import Problem

    if args.objectives is not None:
        names = [o.strip() for o in args.objectives.split(",") if o.strip()]
        twice = sorted({n for n in names if names.count(n) > 1})
        if twice:
            raise ValueError(f"--objectives names {twice[0]!r} twice")
        return [(n, False) for n in names]
    return list(Problem.from_config(cfg["problem"]).objectives)


def _check_objectives(objectives, cfg, where: str, least: int) -> None:
    from bev_mdo.config import resolve_disciplines

    if len(objectives) < least:
        raise ValueError(f"{where}: pareto needs two or more objectives: list them in problem.objectives "
                         "(e.g. [f1, {name: f2, maximize: true}]) or give --objectives a,b")
    produced = {o for d in resolve_disciplines(cfg) for o in d.outputs}
    for name, _ in objectives:
        if name not in produced:
            raise ValueError(f"{where}: objective {name!r} is not produced by any discipline; "
                             f"outputs: {', '.join(sorted(produced))}")


def _units(cfg) -> dict:
    from bev_mdo.config import resolve_disciplines
    from bev_mdo.mdo.units import run_units

    return run_units(resolve_disciplines(cfg))


def run(args) -> int:
    from bev_mdo.config import load_config

    if args.generations < 1 or args.pop < 4:
        raise ValueError(f"--generations must be >= 1 and --pop >= 4, got {args.generations}, {args.pop}")
    if getattr(args, "instances", None) and args.transport != "ros":
        raise ValueError("--instances needs --transport ros (pools of discipline nodes)")
    from bev_mdo.cli import overrides

    cfg = overrides.load(args)  # a bad key, topology, variable or override exits 2 here
    if args.topology or args.all_topologies:
        raw = _read_raw(args.config)
        if overrides.given(args):  # the command line's overrides, checked against the config as written
            raw = overrides.apply(raw, args, overrides.known_names(load_config(args.config)))
        return _study(args, raw)
    objectives = _objectives(args, cfg)
    _check_objectives(objectives, cfg, str(args.config), 2)
    out, bag = _out_dirs(args, cfg.get("name", "run"))
    run_id = uuid.uuid4().hex[:16]
    session = _session(args, cfg, out, bag, run_id, [cfg])
    print(f"NSGA-II {args.pop} x {args.generations} over {args.transport}: "
          f"{', '.join(n + (' (max)' if m else '') for n, m in objectives)}", file=sys.stderr)
    with session:
        def on_front(front, final):
            session.sink.publish(front_message(front, run_id=run_id, topology="", final=final))

        with session.evaluator(cfg, "front") as ev:
            res = _nsga2(cfg, ev, objectives, args, on_front)
    write_front(out / "front.csv", res)
    doc = {"config": str(args.config), "transport": args.transport, "run_id": run_id, "bag": str(bag),
           "objectives": [{"name": n, "maximize": m} for n, m in objectives],
           "design_variables": list(res.names), "generations": args.generations, "pop": args.pop,
           "seed": args.seed, "evaluations": res.evaluations, "batches": res.batches,
           "wall_time_s": res.wall_time_s, "evaluations_per_s": res.evaluations / max(res.wall_time_s, 1e-12),
           "front": [{k: float(v[i]) for k, v in res.values.items()} for i in range(len(res.X))],
           **session.stats}
    pngs = [] if args.no_plots else plot_front(out, res, _units(cfg))
    print(f"front: {len(res.X)} non-dominated feasible designs, {res.evaluations} evaluations in "
          f"{res.batches} batches, {res.wall_time_s:.1f} s")
    what = ", ".join(p.name for p in pngs) if pngs else "no plots: --no-plots"
    print(f"wrote {out}/ (front.csv, front.json, {what}, bag/ with {session.sink.published} ParetoFront messages)")
    return _finish(out / "front.json", doc, session)


def _finish(path: Path, doc: dict, session) -> int:
    failed = session.stats.get("recorder_failed")  # known only once the session stopped its processes
    if failed:
        doc["recorder_failed"] = failed
    path.write_text(json.dumps(doc, indent=2, default=float))
    if failed:
        print(f"warning: {failed}", file=sys.stderr)
        return 3
    return 0


def _out_dirs(args, name: str) -> tuple[Path, Path]:
    stamp = time.strftime("%Y%m%d_%H%M%S")
    out = Path(args.out) if args.out else Path("bags") / f"{name}_pareto_{stamp}"
    bag = out / "bag"
    if bag.exists():
        raise ValueError(f"{bag} already exists; choose another --out")
    return out, bag


def _session(args, raw, out: Path, bag: Path, run_id: str, configs):
    from bev_mdo import sessions

    if args.transport == "ros":
        from bev_mdo.cli.ros_args import ros_section
        from bev_mdo.config import discipline_names
        from bev_mdo.ros.launch import parse_instances

        instances = parse_instances(args.instances, discipline_names(configs[0]))
        out.mkdir(parents=True, exist_ok=True)
        return sessions.ParetoRosSession(raw, ros_section(raw, args), out, bag, run_id, instances=instances)
    out.mkdir(parents=True, exist_ok=True)
    return sessions.ParetoInProcessSession(raw, bag, run_id)


def _study(args, raw) -> int:
    """The BEV topology study (thesis §4.4): one front per topology, the benchmark, the picks."""
    from bev_mdo.config import load_config
    from bev_mdo.models.topology import TOPOLOGIES, get_topology

    from bev_mdo.config import discipline_names
    from bev_mdo.disciplines import TOPOLOGY_DISCIPLINES

    topologies = list(TOPOLOGIES) if args.all_topologies else [get_topology(args.topology).name]
    if not set(discipline_names(load_config(args.config))) & set(TOPOLOGY_DISCIPLINES):
        raise ValueError(f"{args.config}: --topology and --all-topologies study the BEV problem's powertrain "
                         f"topologies; this config has none of the disciplines {', '.join(TOPOLOGY_DISCIPLINES)} "
                         "(without them, bev-mdo pareto runs NSGA-II on the config as written)")
    configs = {}
    for t in topologies:
        try:
            configs[t] = load_config(study.config_for_topology(raw, t))
        except ValueError as exc:  # the file and the topology, not <config>
            raise ValueError(f"{args.config} ({t}): {str(exc).removeprefix('<config>: ')}") from None
    first = next(iter(configs.values()))
    objectives = _objectives(args, first) or [(o, False) for o in OBJECTIVES]
    for t, cfg in configs.items():
        _check_objectives(objectives, cfg, f"{args.config} ({t})", 1)
    out, bag = _out_dirs(args, raw.get("name", "run"))
    run_id = uuid.uuid4().hex[:16]
    results, bench, timing = {}, {}, {}
    session = _session(args, raw, out, bag, run_id, list(configs.values()))
    with session:
        for t, cfg in configs.items():
            print(f"{t}: NSGA-II {args.pop} x {args.generations} over {args.transport}", file=sys.stderr)

            def on_front(front, final, t=t):
                session.sink.publish(front_message(front, run_id=run_id, topology=t, final=final))

            with session.evaluator(cfg, t) as ev:
                res = _nsga2(cfg, ev, objectives, args, on_front, bench=(bench, t))
            results[t] = res
            timing[t] = {"wall_time_s": res.wall_time_s, "evaluations": res.evaluations, "batches": res.batches,
                         "mean_generation_s": float(np.mean(res.generation_times_s)),
                         "evaluations_per_s": res.evaluations / max(res.wall_time_s, 1e-12),
                         "design_variables": {d["name"]: [d["lower"], d["upper"]] for d in _bounds(cfg)}}
            write_front(out / f"pareto_{t}.csv", res)
    study.write_benchmark(out / "benchmark.csv", bench)
    warnings = study.torque_warnings(bench)
    for w in warnings:
        print(w, file=sys.stderr)
    names = [n for n, _ in objectives]
    summary = {"config": str(args.config), "transport": args.transport, "run_id": run_id, "bag": str(bag),
               "objectives": names, "generations": args.generations, "pop": args.pop, "seed": args.seed,
               "timing": timing, "benchmark": bench, "picks": study.picks(results, bench), "out": str(out),
               "warnings": warnings, **session.stats}
    pngs = []
    if not args.no_plots:
        cyc = first.get("cycle") or {}
        pngs = study.plots(out, results, bench, names, cyc.get("name", "") if isinstance(cyc, dict) else "")
    for t in topologies:
        r = results[t]
        print(f"{t}: {len(r.X)} non-dominated designs, {r.evaluations} evaluations in {r.batches} batches, "
              f"{timing[t]['wall_time_s']:.1f} s")
    what = ", ".join(p.name for p in pngs) if pngs else (
        "no plots: --no-plots" if args.no_plots else "no plots: one objective has no trade-off to draw")
    print(f"wrote {out}/ (pareto_*.csv, benchmark.csv, summary.json, {what}, "
          f"bag/ with {session.sink.published} ParetoFront messages)")
    return _finish(out / "summary.json", summary, session)


def _bounds(cfg) -> list[dict]:
    from bev_mdo.mdo.problem import Problem

    return [{"name": d.name, "lower": d.lower, "upper": d.upper} for d in Problem.from_config(cfg["problem"]).design_variables]


def front_message(front, **kw):
    """A ParetoFront message of one generation's front (see bev_mdo.ros.pareto_publisher)."""
    from bev_mdo.ros.pareto_publisher import front_message as make

    return make(front, **kw)


def _nsga2(cfg, evaluator, objectives, args, on_front=None, bench=None):
    from bev_mdo.config import run_settings
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.pareto import run_nsga2

    form = build_formulation(run_settings(cfg), evaluator, "mdf")
    res = run_nsga2(form, objectives, pop_size=args.pop, generations=args.generations, seed=args.seed,
                    on_generation=lambda g, n, s: print(f"  gen {g}: {n} evaluations, {s:.2f} s", file=sys.stderr),
                    on_front=on_front)
    if bench is not None:  # the study's benchmark design, through the same formulation
        table, topology = bench
        table[topology] = study.benchmark(form, topology)
    return res


def write_front(path: Path, res) -> None:
    """The front's designs as CSV: design variables, objectives, then every other MDA variable."""
    cols = list(res.names) + [o for o in res.objectives if o not in res.names]
    cols += sorted(k for k in res.values if k not in cols)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for i in range(len(res.X)):
            w.writerow([f"{float(res.values[c][i]):.10g}" if c in res.values else "" for c in cols])


def plot_front(out: Path, res, units: dict | None = None) -> list[Path]:
    """One scatter plot per pair of objectives, ``front_<b>_vs_<a>.png``. Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bev_mdo.mdo import units as un

    def label(name):
        return un.label(name, units or {})

    written = []
    for i, xk in enumerate(res.objectives):
        for yk in res.objectives[i + 1:]:
            fig, ax = plt.subplots(figsize=(6.0, 4.5))
            ax.scatter(res.values[xk], res.values[yk], s=14, color="C0",
                       label=f"non-dominated feasible designs ({len(res.X)})")
            ax.set_xlabel(label(xk))
            ax.set_ylabel(label(yk))
            ax.set_title(f"Pareto front, NSGA-II: {res.evaluations} evaluations", fontsize=10)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
            fig.tight_layout()
            path = out / f"front_{yk}_vs_{xk}.png"
            fig.savefig(path, dpi=120)
            plt.close(fig)
            written.append(path)
    return written
