"""NSGA-II Pareto fronts (pymoo, mdo/pareto.py) over a config's MDA, in process or over ROS: the core
of ``Study.pareto`` and ``bev-mdo pareto``.

Every generation is ONE batch of the whole population through the evaluator the other commands use.
A run writes into its folder ``out``: ``bag/`` (one ParetoFront per generation; over ROS the
recorder node's bag, with every request and result), ``front.csv`` (the feasible non-dominated
designs, every MDA variable), ``front.json`` (the same, the objectives, the columns' declared units, the
run's figures, its failed evaluations and, with no feasible design, the least violated one) and, unless
``plots=False``, one ``front_<b>_vs_<a>.png`` per pair of objectives.
"""
from __future__ import annotations

import csv
import time
import uuid
from pathlib import Path

from bev_mdo import jsontext
from bev_mdo.api.errors import InputError
from bev_mdo.api.evaluate import ceilings as output_ceilings
from bev_mdo.api.evaluate import declared_units
from bev_mdo.api.transport import Transport
from bev_mdo.mdo.vectors import did_you_mean
from bev_mdo.figures import styled, subplots


def run(cfg, objectives: list[str] | None = None, *, generations: int = 30, pop: int = 100, seed: int = 1,
        out: str | None = None, transport=None, instances: str | int | dict | None = None, plots: bool = True,
        source: str = "<config>", on_generation=None) -> tuple[dict, object]:
    """(the front.json document, mdo.pareto's result) of one NSGA-II run; ``objectives``: outputs to
    minimise (default: the config's ``problem.objectives``)."""
    from bev_mdo import interrupts
    from bev_mdo.api.runbag import claim_new_bag, interrupted_note
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.pareto import hypervolume_reference

    cfg = RunConfig.of(cfg)
    transport = Transport.of(transport)
    check_sizes(generations, pop, instances, transport)
    objs = objectives_of(objectives, cfg)
    check_objectives(objs, cfg, source, 2)
    out, bag = out_dirs(out, cfg.name)
    run_id = uuid.uuid4().hex[:16]
    with claim_new_bag(bag, "--out", out):  # of two runs given the same --out at once, one is refused here
        interrupts.note_bag(lambda: interrupted_note(bag, "front"))  # a signal from now on: what the bag holds
        sess = session(transport, instances, cfg, out, bag, run_id, [cfg])
        from bev_mdo.ros.pareto_publisher import front_message  # loaded by the session already

        with sess:
            def on_front(front, final):
                sess.sink.publish(front_message(front, run_id=run_id, topology="", final=final))

            with sess.evaluator(cfg, "front") as ev:
                res = nsga2(cfg, ev, objs, pop, generations, seed, on_front, on_generation=on_generation)
    write_front(out / "front.csv", res)
    units = declared_units(cfg)
    doc = {"config": source, "transport": transport.transport, "run_id": run_id, "bag": str(bag),
           "objectives": [{"name": n, "maximize": m} for n, m in objs],
           "design_variables": list(res.names), "generations": generations, "pop": pop,
           "seed": seed, "evaluations": res.evaluations, "batches": res.batches,
           "wall_time_s": res.wall_time_s, "evaluations_per_s": res.evaluations / max(res.wall_time_s, 1e-12),
           "hypervolume_by_generation": res.hypervolume, "front_size_by_generation": res.front_sizes,
           "hypervolume_reference": hypervolume_reference([n for n, _ in objs]),  # mdo.pareto.hypervolumes
           **outcome(res, units),
           "front": [{k: float(v[i]) for k, v in res.values.items()} for i in range(len(res.X))],
           "units": {k: units[k] for k in front_columns(res) if k in units},
           **sess.stats, "out": str(out), "published": sess.sink.published,
           "plots": [str(p) for p in plot_front(out, res, units)] if plots else []}
    finish(out / "front.json", doc, sess, skip=("out", "published", "plots"))
    return doc, res


def outcome(res, units: dict) -> dict:
    """What front.json / summary.json say of a run beside its front: its failed evaluations (with the first
    error), those its design check ruled out (a motor that cannot follow the cycle) and, with no feasible
    design, the least violated one (each broken constraint with its output's declared unit)."""
    doc = {"failed_evaluations": res.failed, "first_error": res.first_error,
           "cannot_follow_evaluations": res.cannot_follow}
    if res.least_violated is not None:
        least = res.least_violated
        doc["least_violated"] = {**least, "constraints": [{**c, "unit": units.get(c["output"], "")}
                                                          for c in least["constraints"]]}
    return doc


MAX_POP = 5_000  # 5,000^2 x 8 bytes: 0.2 GB for one of the sort's matrices (0.8 GB for the merged population's)


def check_sizes(generations: int, pop: int, instances, transport) -> None:
    if generations < 1 or pop < 4:
        raise InputError(f"--generations must be >= 1 and --pop >= 4, got {generations}, {pop}")
    if pop > MAX_POP:  # pymoo's non-dominated sort allocates pop x pop numbers and more: 7.28 TiB at a million
        raise InputError(f"--pop {pop}: at most {MAX_POP:,} (NSGA-II's non-dominated sort holds pop x pop matrices "
                         f"and larger: {8 * pop ** 2 / 2 ** 30:,.0f} GiB at least here); more --generations explore "
                         "further")
    transport = Transport.of(transport)
    transport.refuse_attach("pareto")
    if instances and transport.transport != "ros":
        raise InputError("--instances needs --transport ros (pools of discipline nodes)")
    transport.refuse_ros_only()  # --domain-id, --discovery, ... were ignored silently


def objectives_of(names: list[str] | None, cfg) -> list[tuple[str, bool]]:
    """(name, maximize) of the objectives: ``names`` (minimised), else the config's."""
    from bev_mdo.config import RunConfig

    if names is not None:
        twice = sorted({n for n in names if list(names).count(n) > 1})
        if twice:
            raise InputError(f"--objectives names {twice[0]!r} twice")
        return [(n, False) for n in names]
    return list(RunConfig.of(cfg).problem.objectives)


def check_objectives(objectives, cfg, where: str, least: int) -> None:
    from bev_mdo.config import RunConfig

    if len(objectives) < least:
        raise InputError(f"{where}: pareto needs two or more objectives: list them in problem.objectives "
                         "(e.g. [f1, {name: f2, maximize: true}]) or give --objectives a,b")
    produced = {o for d in RunConfig.of(cfg).disciplines for o in d.outputs}
    for name, _ in objectives:
        if name not in produced:
            raise InputError(f"{where}: objective {name!r} is not produced by any discipline; "
                             f"{did_you_mean(name, produced)}outputs: {', '.join(sorted(produced))}")


def finish(path: Path, doc: dict, sess, skip=()) -> None:
    """Write ``doc`` (less the keys in ``skip``) to ``path``, with the recorder's failure if any."""
    failed = sess.stats.get("recorder_failed")  # known only once the session stopped its processes
    if failed:
        doc["recorder_failed"] = failed
    jsontext.write(path, {k: v for k, v in doc.items() if k not in skip})


def out_dirs(out: str | None, name: str) -> tuple[Path, Path]:
    stamp = time.strftime("%Y%m%d_%H%M%S")
    out = Path(out) if out else Path("bags") / f"{name}_pareto_{stamp}"
    bag = out / "bag"
    from bev_mdo.api.runbag import check_new_bag

    check_new_bag(bag, "--out", out)  # early, before the study is set up; claimed when it starts
    return out, bag


def session(transport, instances, raw, out: Path, bag: Path, run_id: str, configs):
    from bev_mdo import sessions

    if Transport.of(transport).transport == "ros":
        from bev_mdo.api.transport import ros_section
        from bev_mdo.config import discipline_names
        from bev_mdo.processes import parse_instances

        parsed = parse_instances(instances, discipline_names(configs[0]))
        out.mkdir(parents=True, exist_ok=True)
        return sessions.ParetoRosSession(raw, ros_section(raw, transport), out, bag, run_id, instances=parsed)
    out.mkdir(parents=True, exist_ok=True)
    return sessions.ParetoInProcessSession(raw, bag, run_id)


def nsga2(cfg, evaluator, objectives, pop: int, generations: int, seed: int, on_front=None, bench=None,
          on_generation=None):
    """mdo.pareto.run_nsga2 over the MDF formulation of ``cfg``; ``bench=(table, topology)`` adds the
    topology study's benchmark design to ``table``."""
    from bev_mdo.config import RunConfig
    from bev_mdo.mdo.driver import build_formulation, design_check
    from bev_mdo.mdo.pareto import run_nsga2

    run = RunConfig.of(cfg)
    form = build_formulation(run.settings, evaluator, "mdf")
    ceilings = {o: c for o, (c, _) in output_ceilings(run).items()}
    # the check optimize and evaluate apply (a motor that cannot follow the cycle): an infeasible design here too
    check = None if run.settings.design_check is None else (
        lambda values: design_check(run.settings, form.problem, values))
    params = form.problem.parameters  # beside a batch's columns, which win (as design_check adds them)
    batch = None if run.settings.designs_check is None else (
        lambda values: run.settings.designs_check({**values, **{k: v for k, v in params.items() if k not in values}}))
    res = run_nsga2(form, objectives, pop_size=pop, generations=generations, seed=seed,
                    on_generation=on_generation or (lambda g, n, s: None), on_front=on_front, ceilings=ceilings,
                    design_check=check, batch_check=batch)
    if bench is not None:  # the study's benchmark design, through the same formulation
        from bev_mdo.studies import topologies as study

        table, topology = bench
        table[topology] = study.benchmark(form, topology)
    return res


def front_columns(res) -> list[str]:
    """The columns of front.csv: design variables, objectives, then every other MDA variable."""
    cols = list(res.names) + [o for o in res.objectives if o not in res.names]
    return cols + sorted(k for k in res.values if k not in cols)


def write_front(path: Path, res) -> None:
    """The front's designs as CSV (``front_columns``; their units: front.json's or summary.json's ``units``)."""
    cols = front_columns(res)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for i in range(len(res.X)):
            w.writerow([f"{float(res.values[c][i]):.10g}" if c in res.values else "" for c in cols])


@styled
def plot_front(out: Path, res, units: dict | None = None) -> list[Path]:
    """One scatter plot per pair of objectives, ``front_<b>_vs_<a>.png``. Returns the files written."""
    from bev_mdo.api.evaluate import axis_label

    label = axis_label(units)
    written = []
    for i, xk in enumerate(res.objectives):
        for yk in res.objectives[i + 1:]:
            fig, ax = subplots(figsize=(6.0, 4.5))
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
            written.append(path)
    return written
