"""``bev-mdo pareto CONFIG [--objectives A,B[,...]] [--transport ros|inprocess] [--instances N|NAME=N]
[--generations G --pop P --seed S] [--out DIR] [--topology T | --all-topologies]``.

NSGA-II (bev_mdo.api.pareto) over the config's MDA for any problem with two or more objectives:
the config's ``problem.objectives`` (each an output name, minimised, or ``{name, maximize: true}``),
or ``--objectives a,b`` (minimised). The problem's constraints are pymoo's inequality constraints.
Writes into ``--out`` (default ``bags/<name>_pareto_<time>/``) ``bag/`` (one ParetoFront per
generation on /bev_mdo/pareto_front, ``final`` on the last), ``front.csv``, ``front.json`` and
``front_<b>_vs_<a>.png``.

``--topology T`` / ``--all-topologies``: the thesis' chapter-4 topology study of the BEV problem
(§4.4; bev_mdo.studies.topologies), per topology: ``pareto_<T>.csv``, ``benchmark.csv`` (Table 4-4
design, beside Table 4-5 for the thesis vehicle), ``fig_4_5_energy_accel.png``, ``fig_4_6_energy_cost.png``,
``summary.json``.

Exit status: 0 a front of feasible designs (every studied topology's); 1 no feasible design (the least violated
one is named) or every evaluated design failed (the first error is named); 2 a user mistake; 3 the recorder failed.
"""
from __future__ import annotations

import argparse
import copy
import sys
import uuid
from pathlib import Path

import numpy as np

from bev_mdo.api.errors import InputError
from bev_mdo.studies import topologies as study

OBJECTIVES = study.OBJECTIVES  # the study's default (energy, 0-100 km/h time, cost)


def register(subparsers) -> None:
    from bev_mdo.cli.flags import seed

    p = subparsers.add_parser("pareto")
    p.add_argument("config", help="run config YAML (e.g. examples/pareto/srn.yaml, config/topologies_artemis.yaml)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--topology", default=None, action=_Once,
                   help="topology study: SM-SA, DM-DA, IWM-SA or IWM-DA (BEV problem)")
    g.add_argument("--all-topologies", action="store_true", help="topology study: all four topologies")
    p.add_argument("--generations", type=int, default=30)
    p.add_argument("--pop", type=int, default=100, help="population size (one batch per generation)")
    p.add_argument("--seed", type=seed, default=1)
    p.add_argument("--objectives", default=None, metavar="A,B[,C]",
                   help="outputs to minimise (default: the config's problem.objectives)")
    p.add_argument("--out", default=None, help="output (bag) directory, default bags/<name>_pareto_<time>")
    p.add_argument("--no-plots", action="store_true")
    from bev_mdo.cli.flags import add_layout_arguments, add_override_arguments, add_transport_arguments

    add_layout_arguments(p, compose=False)  # a population is one batch
    add_transport_arguments(p, attach=False, record=None)
    add_override_arguments(p, single_objective=False)
    p.set_defaults(func=run)


class _Once(argparse.Action):
    """A flag given once: a second --topology silently replaced the first."""

    def __call__(self, parser, namespace, values, option_string=None):
        if getattr(namespace, self.dest) is not None:
            parser.error(f"{option_string} given twice ({getattr(namespace, self.dest)} and {values}): one "
                         "topology, or --all-topologies")
        setattr(namespace, self.dest, values)


def run(args) -> int:
    from bev_mdo.api import pareto
    from bev_mdo.api.transport import Transport
    from bev_mdo.cli import flags

    pareto.check_sizes(args.generations, args.pop, args.instances, args)
    names = None if args.objectives is None else [o.strip() for o in args.objectives.split(",")]
    if names is not None and not all(names):  # "f1,,f2" or "f1,": a name left out is a typo, not a list
        raise InputError(f"--objectives {args.objectives!r}: an empty name; give A,B[,C]")
    if args.topology or args.all_topologies:
        from bev_mdo.api import overrides
        from bev_mdo.config import RunConfig, read_config_file

        raw = read_config_file(args.config)  # the overrides go to each topology's problem (_study)
        return _study(args, raw, RunConfig.load(raw, where=str(args.config)), names, overrides.from_args(args))
    cfg = flags.load_config(args)  # a bad file, key, name, topology, variable or override exits 2 here
    objs = pareto.objectives_of(names, cfg)
    pareto.check_objectives(objs, cfg, str(args.config), 2)
    pareto.out_dirs(args.out, cfg.name)  # an --out in use is refused before the run's first line
    print(f"NSGA-II {args.pop} x {args.generations} over {args.transport}: "
          f"{', '.join(n + (' (max)' if m else '') for n, m in objs)}", file=sys.stderr)
    doc, res = pareto.run(cfg, names, generations=args.generations, pop=args.pop, seed=args.seed, out=args.out,
                          transport=Transport.of(args), instances=args.instances,
                          plots=not args.no_plots, source=str(args.config), on_generation=_generation)
    print(f"front: {_front(res, doc.get('least_violated'))}, {res.evaluations} evaluations in {res.batches} batches, "
          f"{res.wall_time_s:.1f} s")
    _notes(res)
    _settling(res)
    what = ", ".join(Path(p).name for p in doc["plots"]) if doc["plots"] else "no plots: --no-plots"
    print(f"wrote {doc['out']}/ (front.csv, front.json, {what}, bag/ with {doc['published']} ParetoFront messages)")
    return _status(doc, [res])


def _front(res, least: dict | None = None) -> str:
    """'N non-dominated feasible designs', or why there is none: every evaluated design failed (the first
    error), or none is feasible (``least``: api.pareto.outcome's least violated design, its broken constraints
    in their units); the failed evaluations counted."""
    failed = f"{res.failed} of {res.evaluations} evaluated designs failed (first: {res.first_error})"
    if res.evaluations and res.failed == res.evaluations:
        return f"no design: every one of the {res.evaluations} evaluated designs failed (first: {res.first_error})"
    if len(res.X):
        plural = "s" if len(res.X) > 1 else ""
        return f"{len(res.X)} non-dominated feasible design{plural}" + (f"; {failed}" if res.failed else "")
    return "no feasible design" + (f" ({_least(least)})" if least else "") + (f"; {failed}" if res.failed else "")


def _least(least: dict) -> str:
    """'least violated: x1=5, x2=0 breaks c1 <= -1: its c1 is 0 m**2; ...' (and why it cannot follow its cycle)."""
    def unit(c):
        return f" {c['unit']}" if c.get("unit") not in (None, "", "1") else ""

    why = [f"breaks {c['constraint']}{unit(c)}: its {c['output']} is {c['value']:.6g}{unit(c)}"
           for c in least["constraints"]] + list(least["cannot_follow"])
    design = ", ".join(f"{k}={v:.6g}" for k, v in least["design"].items())
    return f"least violated: {design} " + "; ".join(why)


def _notes(res, label: str = "") -> None:
    if res.cannot_follow:  # as sweep says it: infeasible, whatever the constraints
        print(f"{label}note: {res.cannot_follow} of {res.evaluations} evaluated designs cannot follow the drive cycle "
              "(their motor falls short of the drive force or over its speed limit): infeasible, not on the front")


def _settling(res, label: str = "") -> None:
    from bev_mdo.mdo.pareto import settling_line

    if (line := settling_line(res.hypervolume, sizes=res.front_sizes)):
        print(f"{label}{line}")


def _power_range(cfg, topology: str) -> str:
    """The motor power bounds of one topology's study, per motor and in total: an in-wheel motor_kw is per
    motor, so a config's bounds for one motor (SM-SA's 40-130 kW) give an IWM-DA car 160-520 kW (a Taycan-like
    trial ranked a 745 kW IWM-DA beside a 322 kW DM-DA; a thesis reader could not reach its 20 kW motors)."""
    from bev_mdo.models.topology import get_topology

    t, dvs = get_topology(topology), {d.name: d for d in cfg.problem.design_variables}
    axles = [(n, k) for n, k in (("motor_kw", t.front_motors), ("motor_rear_kw", t.rear_motors)) if k and n in dvs]
    per = ", ".join(f"{n} [{dvs[n].lower:g}, {dvs[n].upper:g}] kW" + (f" x {k} motors" if k > 1 else "") for n, k in axles)
    lo, hi = (sum(getattr(dvs[n], side) * k for n, k in axles) for side in ("lower", "upper"))
    return f"motor power {per}: {lo:g}-{hi:g} kW in total"


def _generation(g, n, s) -> None:
    print(f"  gen {g}: {n} evaluations, {s:.2f} s", file=sys.stderr)


def _status(doc: dict, results) -> int:
    """The exit status (the module's docstring): 3 the recorder failed, 1 a run without a feasible design."""
    if doc.get("recorder_failed"):
        print(f"warning: {doc['recorder_failed']}", file=sys.stderr)
        return 3
    return 0 if all(len(r.X) for r in results) else 1


def _only(ov, variables: set[str]):
    """The overrides with the bounds and initial values of ``variables`` only (one topology's)."""
    kept = copy.deepcopy(ov)
    kept.bounds = {k: v for k, v in ov.bounds.items() if k in variables}
    kept.initial = {k: v for k, v in ov.initial.items() if k in variables}
    return kept


def _study(args, raw, written, names, ov) -> int:
    """The BEV topology study (thesis §4.4): one front per topology, the benchmark, the picks;
    ``written``: the config's RunConfig; ``names``: the --objectives (None: the config's); ``ov``: the
    command line's overrides, applied to each topology's problem (DM-DA's motor_rear_kw can be bounded;
    a variable one topology lacks, IWM's gear_ratio, is bounded where it exists, and a name no studied
    topology has is refused)."""
    from bev_mdo.api import pareto
    from bev_mdo.config import RunConfig
    from bev_mdo.disciplines import TOPOLOGY_DISCIPLINES
    from bev_mdo.models.topology import TOPOLOGIES, get_topology

    topologies = list(TOPOLOGIES) if args.all_topologies else [get_topology(args.topology).name]
    if not set(written.names) & set(TOPOLOGY_DISCIPLINES):
        raise ValueError(f"{args.config}: --topology and --all-topologies study the BEV problem's powertrain "
                         f"topologies; this config has none of the disciplines {', '.join(TOPOLOGY_DISCIPLINES)} "
                         "(without them, bev-mdo pareto runs NSGA-II on the config as written)")
    from bev_mdo.api import overrides

    configs, own = {}, {}
    for t in topologies:
        try:
            ct = study.config_for_topology(raw, t)
            own[t] = set(ct["problem"]["design_variables"])
            if ov:
                known = overrides.known_names(RunConfig.load(ct))
                ct = overrides.apply(ct, _only(ov, own[t]) if len(topologies) > 1 else ov, known)
            configs[t] = RunConfig.load(ct)
        except ValueError as exc:  # the file and the topology, not <config>
            raise ValueError(f"{args.config} ({t}): {str(exc).removeprefix('<config>: ')}") from None
    for flag, named in (("--bound", ov.bounds), ("--initial", ov.initial)):
        nowhere = sorted(set(named) - set().union(*own.values()))
        if nowhere:
            raise ValueError(f"{flag} {nowhere[0]!r}: not a design variable of any studied topology; "
                             f"they have {sorted(set().union(*own.values()))}")
    first = next(iter(configs.values()))
    objectives = pareto.objectives_of(names, first) or [(o, False) for o in OBJECTIVES]
    pareto.check_objectives(objectives, first, str(args.config), 2)  # one objective: refused for every topology
    for t, cfg in configs.items():
        pareto.check_objectives(objectives, cfg, f"{args.config} ({t})", 2)
    out, bag = pareto.out_dirs(args.out, raw.get("name", "run"))
    run_id = uuid.uuid4().hex[:16]
    results, bench, timing, outcome = {}, {}, {}, {}
    from bev_mdo.api.evaluate import declared_units
    from bev_mdo.mdo.pareto import hypervolume_reference

    hv_ref = hypervolume_reference([n for n, _ in objectives])
    from bev_mdo.api.runbag import claim_new_bag

    with claim_new_bag(bag, "--out", out):  # of two studies given the same --out at once, one is refused here
        session = pareto.session(args, args.instances, raw, out, bag, run_id, list(configs.values()))
        from bev_mdo.ros.pareto_publisher import front_message  # loaded by the session already

        with session:
            for t, cfg in configs.items():
                print(f"{t}: NSGA-II {args.pop} x {args.generations} over {args.transport}; {_power_range(cfg, t)}",
                      file=sys.stderr)

                def on_front(front, final, t=t):
                    session.sink.publish(front_message(front, run_id=run_id, topology=t, final=final))

                with session.evaluator(cfg, t) as ev:
                    res = pareto.nsga2(cfg, ev, objectives, args.pop, args.generations, args.seed, on_front,
                                       bench=(bench, t), on_generation=_generation)
                results[t] = res
                outcome[t] = pareto.outcome(res, declared_units(cfg))
                timing[t] = {"wall_time_s": res.wall_time_s, "evaluations": res.evaluations, "batches": res.batches,
                             "mean_generation_s": float(np.mean(res.generation_times_s)),
                             "evaluations_per_s": res.evaluations / max(res.wall_time_s, 1e-12),
                             "hypervolume_by_generation": res.hypervolume, "hypervolume_reference": hv_ref,
                             "front_size_by_generation": res.front_sizes,
                             "design_variables": {d.name: [d.lower, d.upper] for d in cfg.problem.design_variables}}
                pareto.write_front(out / f"pareto_{t}.csv", res)
    study.write_benchmark(out / "benchmark.csv", bench, configs)
    broken = study.violations(bench, configs)  # the run's constraints each benchmark design breaks
    warnings = study.benchmark_warnings(bench, broken)
    for w in warnings:  # they qualify the results: on stdout with them
        print(w)
    names = [n for n, _ in objectives]
    summary = {"config": str(args.config), "transport": args.transport, "run_id": run_id, "bag": str(bag),
               "objectives": names, "generations": args.generations, "pop": args.pop, "seed": args.seed,
               "timing": timing, "outcome": outcome,
               "units": {k: u for cfg in configs.values() for k, u in declared_units(cfg).items()},
               "benchmark": bench, "benchmark_violations": broken,
               "picks": study.picks(results, bench), "ranking": study.ranking(results, objectives),
               "caveats": study.caveats(results, configs), "out": str(out),
               "warnings": warnings, **session.stats}
    pngs = []
    if not args.no_plots:
        from bev_mdo.cli import energy_cycle_label

        pngs = study.plots(out, results, bench, names, energy_cycle_label(first), broken)  # what the energy is on
    for t in topologies:
        r = results[t]
        print(f"{t}: {_front(r, outcome[t].get('least_violated'))}, {r.evaluations} evaluations in {r.batches} "
              f"batches, {timing[t]['wall_time_s']:.1f} s")
        _notes(r, f"{t}: ")
        _settling(r, f"{t}: ")
    if len(topologies) > 1:
        for line in study.ranking_lines(summary["ranking"]):
            print(line)
    for line in summary["caveats"]:
        print(line)
    what = ", ".join(p.name for p in pngs) if pngs else "no plots: --no-plots"
    print(f"wrote {out}/ (pareto_*.csv, benchmark.csv, summary.json, {what}, "
          f"bag/ with {session.sink.published} ParetoFront messages)")
    pareto.finish(out / "summary.json", summary, session)
    return _status(summary, results.values())

