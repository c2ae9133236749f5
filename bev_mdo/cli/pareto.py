"""``bev-mdo pareto CONFIG [--topology T | --all-topologies] [--transport inprocess|ros]
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

import contextlib
import json
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from bev_mdo.config import plain
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
    p.add_argument("--no-plots", action="store_true")
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
    load_config(args.config)  # validates the config as written (bad topology/variable: exit 2)
    objectives = [o.strip() for o in args.objectives.split(",") if o.strip()]
    topologies = list(TOPOLOGIES) if args.all_topologies else [
        get_topology(args.topology).name if args.topology else study.config_topology(raw)]
    configs = {t: load_config(study.config_for_topology(raw, t)) for t in topologies}
    out.mkdir(parents=True, exist_ok=True)
    run_id = uuid.uuid4().hex[:16]
    results, bench, timing = {}, {}, {}
    session = _RosSession(raw, args, out, bag, run_id) if args.transport == "ros" else _InProcSession(raw, bag, run_id)
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
    return 0


def front_message(front, **kw):
    """A ParetoFront message of one generation's front (see bev_mdo.ros.pareto_publisher)."""
    from bev_mdo.ros.pareto_publisher import front_message as make

    return make(front, **kw)


def _run_one(cfg, evaluator, objectives, args, topology, on_front=None):
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.pareto import run_nsga2

    form = build_formulation(cfg, evaluator, "mdf")
    res = run_nsga2(form, objectives, pop_size=args.pop, generations=args.generations, seed=args.seed,
                    on_generation=lambda g, n, s: print(f"  gen {g}: {n} evaluations, {s:.2f} s", file=sys.stderr),
                    on_front=on_front)
    return res, study.benchmark(form, topology)


class _InProc:
    def __init__(self, cfg):
        from bev_mdo.config import resolve_disciplines
        from bev_mdo.mdo.evaluator import InProcessEvaluator

        self.ev = InProcessEvaluator(resolve_disciplines(cfg))

    def __enter__(self):
        return self.ev

    def __exit__(self, *exc):
        self.ev.close()


class _InProcSession:
    """In process: the fronts go straight into ``<out>/bag`` (BagWriter)."""

    def __init__(self, raw, bag: Path, run_id: str):
        import yaml

        from bev_mdo.ros.pareto_publisher import BagSink

        self.sink = BagSink(bag, {"run_id": run_id, "config_yaml": yaml.safe_dump(plain(raw), sort_keys=False)})
        self.stats = {}

    def evaluator(self, cfg, topology):
        return _InProc(cfg)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.sink.close()


class _RosSession:
    """Over ROS, as ``bev-mdo optimize`` does it: a recorder node writing ``<out>/bag`` for the
    whole run, one set of discipline nodes per topology (the previous set is stopped first: the
    nodes of two topologies answer the same topics), a coordinator (its RosEvaluator) per topology
    and one ParetoFront publisher; the recorder is stopped first, after it acknowledged every front."""

    def __init__(self, raw, args, out: Path, bag: Path, run_id: str):
        self.raw, self.args, self.out, self.bag, self.run_id = raw, args, out, bag, run_id
        self.stats = {"dropped_messages": {}, "retried_requests": 0}
        self.labels: list[str] = []
        self.launcher = self.ctx = self.sink = None

    def __enter__(self):
        import rclpy
        import yaml

        from bev_mdo.cli.optimize import _start_recorder
        from bev_mdo.cli.ros_args import ros_section
        from bev_mdo.ros.client import apply_ros_environment
        from bev_mdo.ros.launch import Launcher
        from bev_mdo.ros.pareto_publisher import RosSink
        from bev_mdo.ros.settings import ros_environment

        self.ros = ros_section(self.raw, self.args)
        apply_ros_environment(self.ros)
        self.logs = self.out / ".logs"
        self.logs.mkdir(parents=True, exist_ok=True)
        from bev_mdo.ros.auth import with_run_key

        self.ros = with_run_key({"ros": self.ros}, self.logs)["ros"]  # signed by default (docs/security.md)
        resolved = self.logs / "config.yaml"
        resolved.write_text(yaml.safe_dump(plain({**self.raw, "ros": self.ros}), sort_keys=False))
        self.launcher = Launcher(ros_environment(self.ros), log_dir=self.logs)
        try:
            self.recorder = _start_recorder(self.launcher, self.bag, resolved, self.run_id)
            self.launcher.supervise()
            self.ctx = rclpy.context.Context()
            rclpy.init(context=self.ctx)
            self.sink = RosSink(self.ctx, self.run_id)
            self.sink.wait_for_recorder(self.recorder, self.ros["discovery_wait_s"])
        except BaseException:
            self.__exit__()
            raise
        return self

    @contextlib.contextmanager
    def evaluator(self, cfg, topology):
        import yaml

        from bev_mdo.config import discipline_entries
        from bev_mdo.ros import coordinator_node
        from bev_mdo.ros.launch import discipline_argv

        cfg = {**cfg, "ros": self.ros}
        wait_s = self.ros["discovery_wait_s"]
        names = coordinator_node.discipline_names(cfg)
        self._stop_disciplines(names, wait_s)
        logs = self.logs / topology
        logs.mkdir(parents=True, exist_ok=True)
        resolved = logs / "config.yaml"
        resolved.write_text(yaml.safe_dump(plain(cfg), sort_keys=False))
        for entry in discipline_entries(cfg):
            label = f"{topology}/{entry['name']}"
            self.launcher.add(label, discipline_argv(entry["name"], str(resolved.resolve()),
                                                     run_id=f"{self.run_id}-{topology}"))
            self.labels.append(label)
        node = coordinator_node.CoordinatorNode(cfg, f"{self.run_id}-{topology}", context=self.ctx)
        try:
            node.evaluator.wait_for_disciplines(names, wait_s, extra_subscribers=self.recorder)
            node.wait_for_recorder(self.recorder, wait_s)
            self._wait_recorder_topics([f"{n}_node" for n in names], wait_s)
            node.evaluator.warm_up(names)
            yield node.evaluator
            for k, v in node.evaluator.dropped.items():
                self.stats["dropped_messages"][k] = self.stats["dropped_messages"].get(k, 0) + v
            self.stats["retried_requests"] += node.evaluator.retried
            # the recorder has every request of this topology and every front so far
            node.wait_for_all_acked(wait_s)
            self.sink.wait_for_all_acked(wait_s)
        finally:
            node.evaluator.close()
            node.destroy_node()

    def _wait_recorder_topics(self, node_names, wait_s: float) -> None:
        """Wait until the recorder's subscriptions matched every publisher these nodes have under
        /bev_mdo/ (their results): a message published before that would be missing from the bag.
        The recorder finds new topics by polling the graph and reports its matches on its status
        topic; a topic's publishers in this process's graph must all be matched there."""
        from rclpy.node import NodeNameNonExistentError

        from bev_mdo.ros.common import PREFIX

        node = self.sink.node
        deadline = time.monotonic() + wait_s
        while True:
            missing = []
            for n in node_names:
                try:
                    topics = [t for t, _ in node.get_publisher_names_and_types_by_node(n, "/")]
                except NodeNameNonExistentError:
                    missing.append(n)
                    continue
                missing += [t for t in topics if t.startswith(PREFIX + "/")
                            and self.sink.recorder_matched.get(t, 0) < node.count_publishers(t)]
            if not missing:
                return
            if time.monotonic() > deadline:
                raise ValueError(f"the recorder did not match the publishers of {missing[0]} within {wait_s:g} s")
            self.sink.spin(0.02)

    def _stop_disciplines(self, names, wait_s: float) -> None:
        """Stop the previous topology's discipline nodes and wait until the graph lost them."""
        for label in self.labels:
            self.launcher.remove(label)
        self.labels = []
        node_names = {f"{n}_node" for n in names}
        deadline = time.monotonic() + wait_s
        while node_names & set(self.sink.node.get_node_names()):
            if time.monotonic() > deadline:
                raise ValueError(f"discipline nodes of the previous topology still on the graph after {wait_s:g} s")
            self.sink.spin(0.02)  # graph polling

    def __exit__(self, *exc):
        import rclpy

        try:
            if self.sink is not None:
                self.sink.wait_for_all_acked(self.ros["discovery_wait_s"])
                self.sink.close()
            if self.ctx is not None:
                rclpy.shutdown(context=self.ctx)
        finally:
            if self.launcher is not None:
                self.launcher.stop(first=("recorder",))
                self.stats["node_restarts"] = {n.label: n.restarts for n in self.launcher.nodes if n.restarts}


