"""`bev-mdo optimize CONFIG`: the main job.

Over ROS (default) it starts one process per discipline and a recorder, runs the
coordinator in this process, shows progress, prints the optimum (beside the config's
``problem.baseline`` when it names one, e.g. the Nissan Leaf in config/leaf_nedc.yaml),
writes the bag and shuts every process down (also on Ctrl-C).
`--transport inprocess` runs the same engine with no ROS at all.

Exit status: 0 feasible optimum, 1 the run finished infeasible, 2 a user mistake. A finished
run always prints its result (with ``--json``, the JSON on stdout), whatever the baseline does.
"""
from __future__ import annotations

import json
import sys
import time
import uuid
from pathlib import Path



def register(sub) -> None:
    p = sub.add_parser("optimize", help="run the distributed MDF/IDF optimisation (the main job)",
                       description="Optimise the config's problem. Over ROS every discipline runs as its own "
                                   "node process on this host (localhost discovery, the config's domain id).")
    p.add_argument("config", help="run config YAML, e.g. config/leaf_nedc.yaml")
    p.add_argument("--formulation", choices=["mdf", "idf"], default=None, help="default: the config's")
    p.add_argument("--optimizer", default=None,
                   help="SLSQP | trust-constr | COBYQA | COBYLA | differential_evolution | chebyshev-pairwise")
    p.add_argument("--transport", choices=["ros", "inprocess"], default="ros")
    p.add_argument("--json", action="store_true", help="print the result as JSON on stdout")
    p.add_argument("--bag", default=None, help="bag directory to write (default: bags/<config name>_<time>)")
    p.add_argument("--no-record", action="store_true", help="do not record the run")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--instances", default=None, metavar="N|NAME=N,...",
                   help="ROS: run N instances of every discipline, or of the named ones; they share each batch "
                        "(ros.pool: share) or all answer it (redundant)")
    p.add_argument("--compose", default="none", metavar="all|none|A+B,C+D",
                   help="ROS: run several disciplines in one process (one executor, several nodes)")
    from bev_mdo.cli.ros_args import add_ros_arguments

    add_ros_arguments(p)
    p.set_defaults(func=run)


def _progress(quiet: bool, to_stderr: bool):
    from bev_mdo.mdo.formulations import FAIL_OBJECTIVE

    out = sys.stderr if to_stderr else sys.stdout

    def show(rec: dict) -> None:
        if quiet:
            return
        idf = rec.get("formulation") == "idf"  # IDF runs no MDA: count discipline evaluations
        n = sum(rec.get("discipline_evaluations", {}).values()) if idf else rec.get("mda_evaluations", 0)
        rate = n / max(rec.get("wall_time_s", 0.0), 1e-9)
        # a design whose evaluation failed carries the optimiser's penalty, not an objective value
        objective = (f"{rec['objective']:12.6f}" if abs(rec["objective"]) < FAIL_OBJECTIVE
                     else f"{'not evaluated':>12s}")
        print(f"iter {rec['iteration']:4d}  {rec['objective_name']} {objective}  "
              f"max violation {rec['max_violation']:9.3g}  {'feasible  ' if rec['feasible'] else 'infeasible'}"
              f"  {rate:9.0f} {'discipline' if idf else 'MDA'} evals/s", file=out, flush=True)

    return show


def _table(result: dict, baseline: dict | None, out) -> None:
    from rich.console import Console
    from rich.table import Table

    sense = "maximised" if result.get("maximize") else "minimised"
    title = f"Optimum ({result['formulation'].upper()}, {result['optimizer']}; {result['objective_name']} {sense})"
    if baseline is not None:
        title += f" beside {baseline['name']}"
    t = Table(title=title)
    t.add_column("quantity")
    t.add_column("optimum", justify="right")
    if baseline is not None:
        t.add_column(baseline["name"], justify="right")

    def row(k, v, ref):
        t.add_row(k, f"{v:.6g}", *([f"{ref:.6g}"] if baseline is not None else []))

    bd, bo = (baseline or {}).get("design", {}), (baseline or {}).get("outputs", {})
    for k, v in result["design"].items():
        row(k, v, bd.get(k, float("nan")))
    for k, v in result["outputs"].items():
        if k not in result["design"]:
            row(k, v, bo.get(k, float("nan")))
    t.add_row("feasible", str(result["feasible"]), *([str(baseline["feasible"])] if baseline is not None else []))
    Console(file=out).print(t)
    if baseline is not None and baseline.get("error"):
        print(f"baseline {baseline['name']}: {baseline['error']}", file=out)
    if result.get("error"):
        print(f"the result point failed: {result['error']}", file=out)
    if not result.get("last_iterate", True):
        print(f"result: iteration {result['result_iteration']}, the best feasible point seen "
              f"(not the optimiser's last iterate, iteration {result['iterations']})", file=out)
    if result.get("fd_failures"):
        print(f"warning: {result['fd_failures']} finite-difference point(s) failed and gave zero derivatives; "
              "the optimiser may have stopped early (see discipline_errors)", file=out)
    print(f"iterations {result['iterations']}, MDA evaluations {result['mda_evaluations']}, "
          f"evaluations per discipline {result['discipline_evaluations']}", file=out)
    print(f"optimiser wall time {result['wall_time_s']:.3f} s (first evaluation to optimum)", file=out)


def run(args) -> int:
    from bev_mdo.config import load_config

    return run_job(load_config(args.config), args)


def run_job(config: dict, args, x0: dict | None = None) -> int:
    """Run one optimisation of a resolved config as the CLI options say; x0 overrides the start."""
    if args.optimizer:
        from bev_mdo.mdo.optimizers import canonical_name

        from bev_mdo.config import check_optimizer_options

        # ValueError names the known optimizers, or the config's option the chosen one does not take
        check_optimizer_options(canonical_name(args.optimizer), (config.get("optimizer") or {}).get("options") or {})
    t_start = time.perf_counter()
    out = sys.stderr if args.json else sys.stdout
    show = _progress(args.quiet, args.json)
    if args.transport == "inprocess":
        result, baseline, extra = _run_inprocess(config, args, show, x0)
    else:
        result, baseline, extra = _run_ros(config, args, show, x0)
    from bev_mdo.cli import runbag  # end-of-run answers: printed, in --json, stored with the bag

    runbag.finish(config, result, extra)
    extra = {k: v for k, v in extra.items() if not k.startswith("_")}
    extra["run_time_s"] = round(time.perf_counter() - t_start, 3)
    if args.json:
        print(json.dumps({**result, "baseline": baseline, **extra}, default=float, indent=2))
    else:
        _table(result, baseline, out)
        print("\n".join(runbag.answers_text(result, args.transport)), file=out)
        for k, v in extra.items():
            print(f"{k}: {v}" if k != "run_time_s" else f"run time {v:.3f} s (config loaded to this line: start-up, "
                  "optimisation, baseline, answers, shut-down)", file=out)
    if extra.get("recorder_failed"):
        print(f"warning: {extra['recorder_failed']}", file=sys.stderr)
        return 3
    return 0 if result["feasible"] else 1


def _baseline(config, evaluator) -> dict | None:
    """The config's ``problem.baseline`` analysed through ``evaluator``: {name, design, outputs, feasible, ...};
    None when the config names no baseline. A failed analysis is reported in ``error``, never raised:
    the run's own result must not be lost to its baseline."""
    from bev_mdo.mdo.driver import evaluate_design

    base = config["problem"].get("baseline")
    if not base:
        return None
    try:
        report = evaluate_design(config, evaluator, base["design"])
    except Exception as exc:  # noqa: BLE001 - reported beside the result
        return {"name": base["name"], "design": dict(base["design"]), "outputs": {}, "feasible": False,
                "ok": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    return {"name": base["name"], **report}


def _run_inprocess(config, args, show, x0=None):
    from bev_mdo.cli.failures import NamingInProcessEvaluator
    from bev_mdo.config import resolve_disciplines
    from bev_mdo.mdo.driver import run_optimization
    from bev_mdo.ros.settings import validate_ros

    ros = validate_ros(config.get("ros"))
    budget = ros["timeout_s"] * (ros["retries"] + 1)  # what a ROS run gives a discipline before its points fail
    ev = NamingInProcessEvaluator(resolve_disciplines(config), timeout_s=budget)
    from bev_mdo.cli.runbag import in_process_bag  # --bag works in process too

    bag, writer, show = in_process_bag(config, args, show)
    res = run_optimization(config, ev, formulation=args.formulation, optimizer=args.optimizer, x0=x0,
                           callback=show)
    out = res.to_dict()
    out.pop("history")
    baseline = _baseline(config, NamingInProcessEvaluator(resolve_disciplines(config), timeout_s=budget,
                                                          errors=ev.errors))
    extra = {"transport": "inprocess", **({"bag": bag} if bag else {}), "_bag_writer": writer}
    if ev.errors.first:
        extra["discipline_errors"] = dict(ev.errors.first)
    return out, baseline, extra


def _run_ros(config, args, show, x0=None):
    import yaml

    from bev_mdo.config import discipline_entries, plain
    from bev_mdo.ros.auth import with_run_key
    from bev_mdo.ros.launch import Launcher, parse_instances, plan_processes, start_recorder
    from bev_mdo.ros.settings import ros_environment

    from bev_mdo.cli.ros_args import ros_section

    ros = ros_section(config, args)
    # the run's config keeps a domain only when the config stated one (a bag resumed later then
    # follows the ROS convention again: flag, config, ROS_DOMAIN_ID, 77)
    stated = (config.get("ros") or {}).get("domain_id") is not None
    config = {**config, "ros": ros if stated else {k: v for k, v in ros.items() if k != "domain_id"}}
    if args.formulation:
        config["formulation"] = args.formulation
    if args.optimizer:
        config["optimizer"] = {**config.get("optimizer", {}), "name": args.optimizer}
    from bev_mdo.ros.client import apply_ros_environment

    env = ros_environment(ros)
    apply_ros_environment(ros)
    run_id = uuid.uuid4().hex[:16]
    stamp_ = time.strftime("%Y%m%d_%H%M%S")
    bag = Path(args.bag) if args.bag else Path("bags") / f"{config.get('name', 'run')}_{stamp_}_{run_id[:6]}"
    if not args.no_record:
        check_new_bag(bag, "--bag")
    logs = bag / "logs"  # node logs and the resolved config, beside the bag in the run's directory
    logs.mkdir(parents=True, exist_ok=True)
    # the per-run key goes beside the bag, never inside it (a bag directory is what users share)
    config = with_run_key(config, bag.parent / ".keys" / bag.name)
    resolved = logs / "config.yaml"
    resolved.write_text(yaml.safe_dump(plain(config), sort_keys=False))
    launcher = Launcher(env, log_dir=logs)
    if not args.quiet:
        print(f"starting {len(discipline_entries(config))} discipline nodes{'' if args.no_record else ' and a recorder'}"
              f" (domain {ros['domain_id']}); waiting up to {ros.get('discovery_wait_s', 20):g} s for them to be "
              f"discovered ...", file=sys.stderr if args.json else sys.stdout, flush=True)
    recorder = 0
    try:
        names = [e["name"] for e in discipline_entries(config)]
        args.instances_parsed = parse_instances(getattr(args, "instances", None), names)
        for label, argv in plan_processes(names, str(resolved.resolve()), run_id=run_id, instance=run_id[:8],
                                          instances=args.instances_parsed,
                                          compose=getattr(args, "compose", None)):
            launcher.add(label, argv)
        if not args.no_record:
            recorder = start_recorder(launcher, bag, resolved, run_id)
        launcher.supervise()
        result, baseline, stats = _coordinate(config, run_id, args, show, recorder, x0,
                                              _acks_needless(launcher) if recorder else None)
    finally:
        launcher.stop(first=("recorder",))
    t_end = time.monotonic()
    tail_s = t_end - stats["t_optimised"]  # after the optimiser: final acknowledgements, shutdown
    tail = {"acks_s": stats["t_acked"] - stats["t_optimised"], "shutdown_s": t_end - stats["t_acked"]}
    restarts = {n.label: n.restarts for n in launcher.nodes if n.restarts}
    recorder_failed = _recorder_failure(launcher, bag) if recorder else None
    extra = {"transport": "ros", "run_id": run_id, "domain_id": ros["domain_id"],
             "bag": None if args.no_record else str(bag), "logs": str(logs),
             "dropped_messages": stats["dropped"], "retried_requests": stats["retried"], "node_restarts": restarts,
             "refused_instances": stats.get("refused_instances", {}),
             "signing": _signing(ros, config), "tail_s": round(tail_s, 3),
             "tail_parts_s": {k: round(v, 3) for k, v in tail.items()}}
    if stats.get("pools"):
        extra["pools"] = stats["pools"]  # per-instance work, throughput and failures (pool.py)
    if stats.get("discipline_errors"):
        extra["discipline_errors"] = stats["discipline_errors"]
    if recorder_failed:
        extra["recorder_failed"] = recorder_failed
    return result, baseline, extra


LEASE_S = 3.0  # participant lease of bev_mdo's Fast DDS profile (bev_mdo/data/fastdds_profile.xml)
ACK_GRACE_S = 1.0  # a live local recorder acknowledges in milliseconds (in DDS threads, not Python's)


def _acks_needless(launcher):
    """When the coordinator's final wait for acknowledgements may end early (they are awaited only so
    the recorder misses nothing): at once when the recorder died, and after ACK_GRACE_S when a node
    died within the last lease, because a killed reader never acknowledges and is matched until its
    lease expires (stalling the end of the run up to 3 s)."""
    started = []

    def needless() -> bool:
        if launcher.node("recorder").died is not None:
            return True
        now = time.monotonic()
        if not started:
            started.append(now)
        return now - started[0] >= ACK_GRACE_S and launcher.died_within(LEASE_S + ACK_GRACE_S)

    return needless


def _recorder_failure(launcher, bag: Path) -> str | None:
    """None if the recorder lived to the end; else a one-line warning, after making the bag
    readable again (its summary and metadata.yaml rebuilt from what was flushed)."""
    node = launcher.node("recorder")
    # died during the run (the supervisor saw it), or did not stop cleanly when told to: killed
    # while the run was ending (after the supervisor stopped), or stuck and killed by stop()
    status = node.died if node.died is not None else (node.proc.returncode if node.proc is not None else None)
    if status in (0, None):
        return None
    note = f"the recorder died (exit status {status}) during the run; the bag holds only what it recorded before"
    try:
        from bev_mdo.bag.repair import repair

        res = repair(bag)
        note += f" ({res.message_count} messages, summary and metadata rebuilt)"
    except (ValueError, OSError) as exc:
        note += f"; the bag could not be repaired: {exc}"
    return note


def _signing(ros: dict, config: dict) -> str:
    """How this run's messages were signed, for the summary."""
    if ros.get("sign_key_file"):
        return f"key file {ros['sign_key_file']}"
    return "per-run key" if (config.get("ros") or {}).get("sign_key_file") else "off (ros.signing: false)"


def check_new_bag(bag: Path, what: str) -> None:
    """A bag may be written to `bag`: ValueError (exit 2) naming it if a bag or a file is there."""
    if bag.exists() and not bag.is_dir():
        raise ValueError(f"{what} {bag}: is a file, not a bag directory")
    if (bag / "metadata.yaml").exists() or any(bag.glob("*.mcap")):
        raise ValueError(f"{what} {bag}: a bag already exists there; choose a new directory")


def _coordinate(config, run_id, args, show, recorder: int, x0=None, recorder_dead=None):
    import rclpy

    from bev_mdo.ros import coordinator_node

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        # The baseline does not depend on the optimum: it is analysed BEFORE the optimisation, so the
        # end of the run evaluates nothing and never waits for a node that died late (a SIGKILLed
        # vehicle_mass after the optimiser's last evaluation stalled the baseline until its restart
        # was discovered: 8.5 s of tail in bench/bench_kill_tail.py).
        seen: dict = {}
        baseline = _ros_baseline(config, run_id, ctx, seen)
        res, stats = coordinator_node.run(config, run_id=run_id, formulation=args.formulation,
                                          optimizer=args.optimizer, x0=x0, on_iteration=show,
                                          recorder_subscribers=recorder, context=ctx,
                                          instances=getattr(args, "instances_parsed", None),
                                          give_up_acks=recorder_dead)
        stats["t_acked"] = time.monotonic()  # the final acknowledgements are in (or given up)
        _merge_baseline_stats(stats, seen)
        out = res.to_dict()
        out.pop("history")
        return out, baseline, stats
    finally:
        rclpy.shutdown(context=ctx)


_DECLARATION_DROPS = ("refused_instance", "info_unsigned", "info_forged", "info_other_run", "info_other_discipline")


def _merge_baseline_stats(stats: dict, seen: dict) -> None:
    """Count what the baseline's evaluator dropped and refused as the run's: its results add up;
    declarations are the same ones the run's evaluator judges (the larger count of the two), and an
    instance refused by either is refused (the run's evaluator, started when everything is
    discovered, may be ready before a foreign declaration reaches it)."""
    if not seen:
        return
    dropped = dict(stats["dropped"])
    for k, v in seen["dropped"].items():
        dropped[k] = max(dropped.get(k, 0), v) if k in _DECLARATION_DROPS else dropped.get(k, 0) + v
    refused = {**seen["refused"], **stats.get("refused_instances", {})}
    dropped["refused_instance"] = len(refused) if refused else dropped.get("refused_instance", 0)
    stats["dropped"] = {k: v for k, v in dropped.items() if v}
    stats["refused_instances"] = refused


def _ros_baseline(config, run_id: str, ctx, seen: dict | None = None) -> dict | None:
    """The config's baseline analysed through the run's nodes (sub-run ``<run>-baseline``); None
    without one. A discipline that never appears raises (the run itself could not start either).
    `seen` gets what its evaluator dropped and refused."""
    from bev_mdo.ros import coordinator_node
    from bev_mdo.ros.evaluator import DisciplineMissing

    if not config["problem"].get("baseline"):
        return None
    node = coordinator_node.CoordinatorNode(config, run_id + "-baseline", context=ctx,
                                            node_name="coordinator_baseline")
    try:
        node.evaluator.wait_for_disciplines(coordinator_node.discipline_names(config), node.discovery_wait_s)
        return _baseline(config, node.evaluator)
    except DisciplineMissing:
        raise
    except Exception as exc:  # noqa: BLE001 - the run's result is printed anyway
        return {"name": config["problem"]["baseline"]["name"], "design": {}, "outputs": {},
                "feasible": False, "ok": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0]}
    finally:
        if seen is not None:
            seen.update(dropped=dict(node.evaluator.dropped), refused=dict(node.evaluator.refused))
        node.evaluator.close()
        node.destroy_node()


