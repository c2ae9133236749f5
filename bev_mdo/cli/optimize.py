"""`bev-mdo optimize CONFIG`: the main job.

Over ROS (default) it starts one process per discipline and a recorder, runs the
coordinator in this process, shows progress, prints the optimum beside the Nissan
Leaf baseline, writes the bag and shuts every process down (also on Ctrl-C).
`--transport inprocess` runs the same engine with no ROS at all.
"""
from __future__ import annotations

import json
import sys
import time
import uuid
from pathlib import Path

from bev_mdo.cli import UsageError

LEAF_BASELINE = {"motor_kw": 80.0, "gear_ratio": 7.94, "battery_kwh": 24.0}


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
        rate = rec.get("mda_evaluations", 0) / max(rec.get("wall_time_s", 0.0), 1e-9)
        # a design whose evaluation failed carries the optimiser's penalty, not an objective value
        objective = (f"{rec['objective']:12.6f}" if abs(rec["objective"]) < FAIL_OBJECTIVE
                     else f"{'not evaluated':>12s}")
        print(f"iter {rec['iteration']:4d}  {rec['objective_name']} {objective}  "
              f"max violation {rec['max_violation']:9.3g}  {'feasible  ' if rec['feasible'] else 'infeasible'}"
              f"  {rate:9.0f} MDA evals/s", file=out, flush=True)

    return show


def _table(result: dict, baseline: dict, out) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title=f"Optimum ({result['formulation'].upper()}, {result['optimizer']}) beside the Nissan Leaf")
    t.add_column("quantity")
    t.add_column("optimum", justify="right")
    t.add_column("Leaf (80 kW, 7.94:1, 24 kWh)", justify="right")
    for k, v in result["design"].items():
        t.add_row(k, f"{v:.4f}", f"{baseline['design'].get(k, float('nan')):.4f}")
    for k, v in result["outputs"].items():
        if k not in result["design"]:
            t.add_row(k, f"{v:.4f}", f"{baseline['outputs'].get(k, float('nan')):.4f}")
    t.add_row("feasible", str(result["feasible"]), str(baseline["feasible"]))
    Console(file=out).print(t)
    print(f"iterations {result['iterations']}, MDA evaluations {result['mda_evaluations']}, "
          f"evaluations per discipline {result['discipline_evaluations']}, wall time {result['wall_time_s']:.3f} s",
          file=out)


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
    out = sys.stderr if args.json else sys.stdout
    show = _progress(args.quiet, args.json)
    if args.transport == "inprocess":
        result, baseline, extra = _run_inprocess(config, args, show, x0)
    else:
        result, baseline, extra = _run_ros(config, args, show, x0)
    if args.json:
        print(json.dumps({**result, "baseline": baseline, **extra}, default=float, indent=2))
    else:
        _table(result, baseline, out)
        for k, v in extra.items():
            print(f"{k}: {v}", file=out)
    if extra.get("recorder_failed"):
        print(f"warning: {extra['recorder_failed']}", file=sys.stderr)
        return 3
    return 0 if result["feasible"] else 1


def _baseline_design(config) -> dict:
    names = list(config["problem"]["design_variables"])
    return {k: v for k, v in LEAF_BASELINE.items() if k in names}


def _run_inprocess(config, args, show, x0=None):
    from bev_mdo.cli.failures import NamingInProcessEvaluator
    from bev_mdo.config import resolve_disciplines
    from bev_mdo.mdo.driver import evaluate_design, run_optimization
    from bev_mdo.ros.settings import validate_ros

    ros = validate_ros(config.get("ros"))
    budget = ros["timeout_s"] * (ros["retries"] + 1)  # what a ROS run gives a discipline before its points fail
    ev = NamingInProcessEvaluator(resolve_disciplines(config), timeout_s=budget)
    res = run_optimization(config, ev, formulation=args.formulation, optimizer=args.optimizer, x0=x0,
                           callback=show)
    out = res.to_dict()
    out.pop("history")
    baseline = evaluate_design(config, NamingInProcessEvaluator(resolve_disciplines(config), timeout_s=budget,
                                                                errors=ev.errors), _baseline_design(config))
    extra = {"transport": "inprocess"}
    if ev.errors.first:
        extra["discipline_errors"] = dict(ev.errors.first)
    return out, baseline, extra


def _run_ros(config, args, show, x0=None):
    import yaml

    from bev_mdo.config import discipline_entries
    from bev_mdo.ros.launch import Launcher, parse_instances, plan_processes
    from bev_mdo.ros.settings import ros_environment

    from bev_mdo.cli.ros_args import ros_section

    ros = ros_section(config, args)
    config = {**config, "ros": ros}
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
    logs = Path("bags") / ".logs" / run_id  # node logs and the resolved config, outside the bag
    logs.mkdir(parents=True, exist_ok=True)
    config = with_run_key(config, logs)
    resolved = logs / "config.yaml"
    resolved.write_text(yaml.safe_dump(_plain(config), sort_keys=False))
    launcher = Launcher(env, log_dir=logs)
    recorder = 0
    try:
        names = [e["name"] for e in discipline_entries(config)]
        args.instances_parsed = parse_instances(getattr(args, "instances", None), names)
        for label, argv in plan_processes(names, str(resolved.resolve()), run_id=run_id, instance=run_id[:8],
                                          instances=args.instances_parsed,
                                          compose=getattr(args, "compose", None)):
            launcher.add(label, argv)
        if not args.no_record:
            recorder = _start_recorder(launcher, bag, resolved, run_id)
        launcher.supervise()
        result, baseline, stats = _coordinate(config, run_id, args, show, recorder, x0)
    finally:
        launcher.stop(first=("recorder",))
    tail_s = time.monotonic() - stats["t_optimised"]  # after the optimiser: acks, baseline, shutdown
    restarts = {n.label: n.restarts for n in launcher.nodes if n.restarts}
    recorder_failed = _recorder_failure(launcher, bag) if recorder else None
    extra = {"transport": "ros", "run_id": run_id, "domain_id": ros["domain_id"],
             "bag": None if args.no_record else str(bag), "logs": str(logs),
             "dropped_messages": stats["dropped"], "retried_requests": stats["retried"], "node_restarts": restarts,
             "refused_instances": stats.get("refused_instances", {}),
             "signing": _signing(ros, config), "tail_s": round(tail_s, 3)}
    if stats.get("pools"):
        extra["pools"] = stats["pools"]  # per-instance work, throughput and failures (pool.py)
    if stats.get("discipline_errors"):
        extra["discipline_errors"] = stats["discipline_errors"]
    if recorder_failed:
        extra["recorder_failed"] = recorder_failed
    return result, baseline, extra


def _recorder_failure(launcher, bag: Path) -> str | None:
    """None if the recorder lived to the end; else a one-line warning, after making the bag
    readable again (its summary and metadata.yaml rebuilt from what was flushed)."""
    node = launcher.node("recorder")
    if node.died is None:
        return None
    note = f"the recorder died (exit status {node.died}) during the run; the bag holds only what it recorded before"
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


def with_run_key(config: dict, logs: Path) -> dict:
    """Signing on by default: without a configured ``ros.sign_key_file`` (and unless
    ``ros.signing: false``) a fresh random key is written to ``<logs>/sign.key`` (mode 0600,
    outside the bag); the resolved config that the nodes and the recorder read names its path
    only, so the key is never on a command line, in the environment or in the bag."""
    ros = dict(config.get("ros") or {})
    if ros.get("sign_key_file") or not ros.get("signing", True):
        return config
    from bev_mdo.ros.auth import new_key_file

    ros["sign_key_file"] = new_key_file(logs)
    return {**config, "ros": ros}


def _start_recorder(launcher, bag: Path, resolved: Path, run_id: str) -> int:
    """Start the recorder node; returns how many extra subscribers it adds per topic."""
    # Not restarted: a second recorder cannot reopen the bag the first one was writing (the run ends
    # with a warning and status 3 instead, the bag repaired up to the recorder's death).
    launcher.add("recorder", [sys.executable, "-m", "bev_mdo.ros.run", "recorder_node", "--output", str(bag),
                              "--config", str(resolved.resolve()), "--run-id", run_id], restart=False)
    return 1


def _coordinate(config, run_id, args, show, recorder: int, x0=None):
    import rclpy

    from bev_mdo.mdo.driver import evaluate_design
    from bev_mdo.ros import coordinator_node

    ctx = rclpy.context.Context()
    rclpy.init(context=ctx)
    try:
        res, stats = coordinator_node.run(config, run_id=run_id, formulation=args.formulation,
                                          optimizer=args.optimizer, x0=x0, on_iteration=show,
                                          recorder_subscribers=recorder, context=ctx,
                                          instances=getattr(args, "instances_parsed", None))
        out = res.to_dict()
        out.pop("history")
        node = coordinator_node.CoordinatorNode(config, run_id + "-baseline", context=ctx,
                                                node_name="coordinator_baseline")
        try:
            node.evaluator.wait_for_disciplines(coordinator_node.discipline_names(config), node.discovery_wait_s)
            baseline = evaluate_design(config, node.evaluator, _baseline_design(config))
        finally:
            node.evaluator.close()
            node.destroy_node()
        return out, baseline, stats
    finally:
        rclpy.shutdown(context=ctx)


def _plain(obj):
    """YAML-safe copy (numpy scalars to floats)."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if hasattr(obj, "item"):
        return obj.item()
    return obj
