"""One optimisation of a resolved config, in process or over ROS: the core of ``Study.optimize``
and of ``bev-mdo optimize`` / ``resume``.

Over ROS it starts one node per discipline (by default in this process, ``compose``) and a
recorder, runs the coordinator here and shuts every process down at the end (also on Ctrl-C).
Every run ends with a first-order check of its result (bev_mdo/mdo/first_order.py) and the
end-of-run answers (bev_mdo/mdo/active.py), stored with the bag when there is one.
"""
from __future__ import annotations

import contextlib
import shutil
import sys
import tempfile
import time
import uuid
from dataclasses import dataclass
from pathlib import Path

from bev_mdo.api.errors import InputError
from bev_mdo.api.transport import Transport


@dataclass
class OptimizeOptions(Transport):
    """What a run may choose beside the config (the ``bev-mdo optimize`` flags of the same names)."""

    formulation: str | None = None  # mdf | idf (default: the config's)
    optimizer: str | None = None  # SLSQP, trust-constr, COBYQA, ... (default: the config's)
    starts: int = 1  # >1: a Latin hypercube of start points (seed), the best end reported
    seed: int = 0  # of the start points, and of an optimiser that draws random numbers (_seeded)
    bag: str | None = None  # bag directory to write (in process: only when given; ROS: a default name)
    bag_flag: str = "--bag"  # the flag that named it, for the line refusing it (resume: --output)
    no_record: bool = False
    quiet: bool = False
    instances: str | int | dict | None = None  # ROS: "N" or "NAME=N,..." (an int, {NAME: N}) instances per discipline
    compose: str | None = "coordinator"  # ROS: where the discipline nodes run (docs/scaling.md)
    fixed_budget: bool = False  # the verdict of a feasible end that is not a verified optimum is still ok
    progress_to_stderr: bool = False  # ROS start-up line on stderr (the CLI's --json)


def run(config, opts: OptimizeOptions, callback=None, x0: dict | list[dict] | None = None) -> dict:
    """The run's JSON document: the result (design, outputs, constraints, first_order, verdict,
    active, ...) with ``baseline``, the transport's figures and ``run_time_s``; ``config``: a
    ``RunConfig`` (a plain config mapping is loaded first). ``x0``: the start, or a multi-start's
    start points."""
    from bev_mdo.config import RunConfig

    config = RunConfig.of(config)
    if opts.optimizer:
        from bev_mdo.config import check_optimizer_options
        from bev_mdo.mdo.optimizers import canonical_name

        # ValueError names the known optimizers, or the config's option the chosen one does not take
        check_optimizer_options(canonical_name(opts.optimizer), config.settings.optimizer.options)
    if opts.formulation or opts.optimizer:  # what the run records (in process too): the formulation and
        engine = {"formulation": opts.formulation} if opts.formulation else {}  # optimiser it ran, for resume
        if opts.optimizer:
            engine["optimizer"] = {**config["optimizer"], "name": opts.optimizer}
        config = config.with_sections(**engine)
    config = _seeded(config, opts.seed)
    opts.refuse_attach("optimize")  # and optimize's own ROS flags in process (--compose counts unless the default)
    opts.refuse_ros_only((("--compose", None if opts.compose == "coordinator" else opts.compose),
                          ("--instances", opts.instances)))
    starts = _starts(opts, x0)  # a bad start count is refused before anything starts or is written
    t_start = time.perf_counter()
    from bev_mdo.api import runbag  # end-of-run answers: in the result, stored with the bag

    show = runbag.RecordTally(callback or (lambda rec: None))  # what the run sends to its bag, for the answers

    # an in-process bag is closed however the run ends: by runbag.finish with the answers, or on the way out of a
    # signal or failure at any step before (without them), from the moment it is opened (in_process_bag)
    with contextlib.ExitStack() as closing:
        if opts.uses_ros:
            result, baseline, extra = _run_ros(config, opts, show, x0, starts)
        else:
            result, baseline, extra = _run_inprocess(config, opts, show, x0, starts, closing)
        runbag.finish(config, result, extra, show)
    extra = {k: v for k, v in extra.items() if not k.startswith("_")}
    extra["run_time_s"] = round(time.perf_counter() - t_start, 3)
    named = {"parameter_set": config.parameter_set} if config.parameter_set else {}  # which set the vehicle's came from
    from bev_mdo.api.evaluate import design_notes, units_of

    if result.get("outputs"):  # what a value at the result means, as evaluate says it (the pack's power limit)
        values = {**config.problem.parameters, **result.get("design", {}), **result["outputs"]}
        if notes := design_notes(config, values):
            named["notes"] = notes
    named["units"] = units_of(config, [*result.get("design", {}), *result.get("outputs", {})])  # as evaluate's JSON
    return {**result, **named, "baseline": baseline, **extra}


def _seeded(config, seed: int):
    """The config whose optimiser draws from ``seed`` (the run's seed, as for the --starts sample) when it draws
    random numbers (optimizers.SEEDED) and its options give no seed or rng: the config a run records (resume
    goes on with the same). Seed 0, the default, is the optimiser's default rng already: the config as it is."""
    from bev_mdo.mdo.optimizers import SEEDED, canonical_name

    section = config["optimizer"]
    options = dict(section.get("options") or {})
    if not seed or canonical_name(section["name"]) not in SEEDED or {"seed", "rng"} & set(options):
        return config
    return config.with_sections(optimizer={**section, "options": {**options, "seed": seed}})


def _run_inprocess(config, opts, show, x0, starts, closing: contextlib.ExitStack):
    from bev_mdo.api.failures import NamingInProcessEvaluator
    from bev_mdo.api.runbag import in_process_bag
    from bev_mdo.mdo.driver import run_optimization
    from bev_mdo.sessions import analyse_baseline

    ev = NamingInProcessEvaluator(config.timed_disciplines())  # prepared before the optimiser's clock, as over ROS
    bag, writer, show = in_process_bag(config, opts, show, closing)  # a bag only when one is asked for
    if starts != 1:
        from bev_mdo.mdo.multistart import run_starts

        res = run_starts(config.settings, ev, starts, seed=opts.seed,
                         formulation=opts.formulation, optimizer=opts.optimizer, callback=show)
    else:
        res = run_optimization(config.settings, ev, formulation=opts.formulation,
                               optimizer=opts.optimizer, x0=x0, callback=show)
    baseline = analyse_baseline(config, NamingInProcessEvaluator(config.timed_disciplines(), errors=ev.errors))
    out = res.summary()
    extra = {"transport": "inprocess", **({"bag": bag} if bag else {}), "_bag_writer": writer}
    if ev.errors.first:
        extra["discipline_errors"] = dict(ev.errors.first)
    if ev.unresponsive:
        extra["unresponsive_disciplines"] = ev.unresponsive
    return out, baseline, extra


def _run_ros(config, opts, show, x0, starts):
    from bev_mdo import interrupts
    from bev_mdo.api.transport import ros_section
    from bev_mdo.processes import parse_instances
    from bev_mdo.sessions import OptimizeRosSession

    ros = ros_section(config, opts)
    # the run's config keeps a domain only when the config stated one (a bag resumed later then
    # follows the ROS convention again: flag, config, ROS_DOMAIN_ID, 77)
    stated = config["ros"].get("domain_id") is not None
    config = config.with_ros(ros if stated else {k: v for k, v in ros.items() if k != "domain_id"})
    run_id = uuid.uuid4().hex[:16]
    stamp_ = time.strftime("%Y%m%d_%H%M%S")
    bag = Path(opts.bag) if opts.bag else Path("bags") / f"{config.name}_{stamp_}_{run_id[:6]}"
    if not opts.no_record or opts.bag:  # (--no-record --bag DIR: logs/ in DIR, beside no other run's)
        from bev_mdo.api.runbag import check_new_bag

        check_new_bag(bag, opts.bag_flag)  # before the flags' checks, as ever; claimed below, before anything is written
    scratch = None
    if opts.no_record and not opts.bag:  # nothing to keep: the logs and the per-run key go in a private temporary
        scratch = Path(tempfile.mkdtemp(prefix="bev_mdo_run_"))  # directory (mode 0700), removed after a run that ended
        bag = scratch / bag.name
    names = list(config.names)
    instances = parse_instances(opts.instances, names)
    where = _where(names, instances, opts.compose)  # a rejected --compose is refused before this line prints
    session = OptimizeRosSession(config, ros, bag, run_id, record=not opts.no_record, instances=instances,
                                 compose=opts.compose)
    with contextlib.ExitStack() as claimed:
        if not opts.no_record or opts.bag:  # the directory is this run's (of two runs given it at once, one is refused)
            from bev_mdo.api.runbag import claim_new_bag, interrupted_note

            claimed.enter_context(claim_new_bag(bag, opts.bag_flag))
        if not opts.no_record:
            interrupts.note_bag(lambda: interrupted_note(bag))  # a signal from now on: what the bag holds
        if not opts.quiet:
            print(f"starting {where}{'' if opts.no_record else ' and a recorder'}"
                  f" (domain {ros['domain_id']}); waiting while discovery makes progress (gives up after "
                  f"{ros['discovery_wait_s']:g} s without) ...",
                  file=sys.stderr if opts.progress_to_stderr else sys.stdout, flush=True)
        with session:
            result, baseline = session.run(opts.formulation, opts.optimizer, x0, show, starts=starts,
                                           seed=opts.seed)
    extra = session.summary()
    if scratch is not None:  # (left in place, for its logs, when the run raised)
        shutil.rmtree(scratch, ignore_errors=True)
        del extra["logs"]
    return result, baseline, extra


def _where(names, instances: dict, compose: str | None) -> str:
    """What the start-up line says runs where: the nodes in this process (--compose coordinator), and the
    processes started for the others (a pool's instances: one each). ValueError on a bad --compose."""
    from bev_mdo.processes import beside_coordinator, node_names_of, plan_processes

    local = beside_coordinator(compose, names, instances)
    plan = plan_processes(names, "", instances=instances, compose=compose)
    started = sum(len(node_names_of(argv)) for _, argv in plan)
    parts = [f"{len(local)} in this process, --compose coordinator"] if local else []
    if plan:
        pools = ", ".join(f"{n} x{k}" for n, k in instances.items() if k > 1)
        parts.append(f"{started} in {len(plan)} other process{'es' if len(plan) > 1 else ''}"
                     + ("" if compose == "coordinator" else f", --compose {compose or 'none'}")
                     + (f", a process per pool instance: {pools}" if pools else ""))
    return f"{len(local) + started} discipline nodes ({'; '.join(parts)})"


def _starts(opts, x0) -> int | list:
    """The run's starts: a count (multi-start: a sample of that many) or, for a multi-start resumed from
    each start's last record, the list of start points ``x0`` is."""
    from bev_mdo.mdo.multistart import check_starts

    starts = int(opts.starts)
    try:
        check_starts(starts)
    except ValueError as exc:
        raise InputError(str(exc)) from None
    if starts > 1 and x0:
        raise InputError("--starts samples its own start points; it cannot be combined with a given start")
    return list(x0) if isinstance(x0, list) else starts
