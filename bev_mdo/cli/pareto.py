"""``bev-mdo pareto CONFIG [--topology T | --all-topologies] [--transport inprocess|ros]
[--generations G --pop P --seed S] [--objectives a,b,c] [--out DIR]``.

Thesis §4.4 (eqs 4-6..4-10): NSGA-II (pymoo) over the config's MDA, minimising energy on the
combined Artemis cycle, 0-100 km/h time and powertrain cost subject to the problem's
constraints (NEDC range >= 175 km, cycle torque/speed feasibility). Every generation is ONE
batch of the whole population through the evaluator (in-process, or the discipline nodes over
ROS). ``--topology`` / ``--all-topologies`` rewrite ``vehicle.topology`` (and the ``topology``
option of any discipline that sets one) and the design variables (``TOPOLOGY_BOUNDS``; the
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
import copy
import csv
import json
import sys
import time
import uuid
from pathlib import Path

import numpy as np

from bev_mdo.config import plain

OBJECTIVES = ("energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd")
TOPOLOGY_DISCIPLINES = ("vehicle_mass", "energy", "acceleration", "cost", "cycle_range")
# design-variable bounds per topology (motor power per motor); used when --topology changes it
TOPOLOGY_BOUNDS = {
    "SM-SA": {"motor_kw": (40.0, 130.0, 80.0), "gear_ratio": (4.0, 9.4, 7.9)},
    "DM-DA": {"motor_kw": (20.0, 90.0, 40.0), "gear_ratio": (4.0, 9.4, 7.9),
              "motor_rear_kw": (20.0, 90.0, 40.0), "gear_ratio_rear": (4.0, 9.4, 7.9)},
    "IWM-SA": {"motor_kw": (20.0, 90.0, 40.0)},
    "IWM-DA": {"motor_kw": (10.0, 70.0, 20.0), "motor_rear_kw": (10.0, 70.0, 20.0)},
}
# Table 4-4 benchmark (80 kW in total, 24 kWh) and Table 4-5 (kerb kg, 0-100 s, US$, kWh/100 km)
BENCHMARK = {"SM-SA": {"motor_kw": 80.0, "gear_ratio": 7.9},
             "DM-DA": {"motor_kw": 40.0, "gear_ratio": 7.9, "motor_rear_kw": 40.0, "gear_ratio_rear": 7.9},
             "IWM-SA": {"motor_kw": 40.0}, "IWM-DA": {"motor_kw": 20.0, "motor_rear_kw": 20.0}}
THESIS_4_5 = {"SM-SA": (1521.0, 9.9, 8920.3, 16.47), "DM-DA": (1572.6, 10.5, 9305.3, 16.64),
              "IWM-SA": (1521.0, 11.18, 9325.7, 15.99), "IWM-DA": (1553.6, 11.47, 10108.0, 16.05)}


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


def config_topology(raw) -> str:
    """The topology a raw config sets (``vehicle.topology``, else a discipline's ``topology``
    option; SM-SA if none). load_config rejects a config where they disagree."""
    from bev_mdo.models.topology import get_topology

    vehicle = raw.get("vehicle") if isinstance(raw.get("vehicle"), dict) else {}
    if "topology" in vehicle:
        return get_topology(vehicle["topology"]).name
    for e in raw.get("disciplines") or []:
        if isinstance(e, dict) and isinstance(e.get("options"), dict) and "topology" in e["options"]:
            return get_topology(e["options"]["topology"]).name
    return "SM-SA"


def config_for_topology(raw, topology: str) -> dict:
    """A copy of the raw config with ``vehicle.topology`` (and any discipline ``topology`` option)
    set to ``topology`` and, if that differs from the config's own, the topology's design
    variables (``TOPOLOGY_BOUNDS``)."""
    from bev_mdo.models.topology import get_topology

    t = get_topology(topology).name
    cfg = copy.deepcopy(raw)
    own = config_topology(raw)
    entries = cfg.get("disciplines")
    if not entries:
        raise ValueError("the config must list its disciplines (vehicle_mass, energy, cycle_range, acceleration, cost)")
    cfg["vehicle"] = {**(cfg.get("vehicle") or {}), "topology": t}
    for e in entries:
        if (isinstance(e, dict) and e.get("name") in TOPOLOGY_DISCIPLINES and "class" not in e
                and isinstance(e.get("options"), dict) and "topology" in e["options"]):
            e["options"]["topology"] = t
    cfg["name"] = f"{raw.get('name', 'run')}_{t}"
    if t != own:
        dvs = dict((cfg.get("problem") or {}).get("design_variables") or {})
        battery = dvs.get("battery_kwh", {"lower": 18.0, "upper": 30.0, "initial": 24.0})
        new = {k: {"lower": lo, "upper": hi, "initial": x0} for k, (lo, hi, x0) in TOPOLOGY_BOUNDS[t].items()}
        new["battery_kwh"] = battery
        cfg.setdefault("problem", {})["design_variables"] = new
    return cfg


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
        get_topology(args.topology).name if args.topology else config_topology(raw)]
    configs = {t: load_config(config_for_topology(raw, t)) for t in topologies}
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
            _write_front(out / f"pareto_{t}.csv", res)
    _write_benchmark(out / "benchmark.csv", bench)
    warnings = torque_warnings(bench)
    for w in warnings:
        print(w, file=sys.stderr)
    picks = _picks(results, bench)
    summary = {"config": str(args.config), "transport": args.transport, "run_id": run_id, "bag": str(bag),
               "objectives": objectives, "generations": args.generations, "pop": args.pop, "seed": args.seed,
               "timing": timing, "benchmark": bench, "picks": picks, "out": str(out), "warnings": warnings,
               **session.stats}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    pngs = []
    if not args.no_plots:
        cyc = (next(iter(configs.values())).get("cycle") or {})
        pngs = _plots(out, results, bench, objectives, cyc.get("name", "") if isinstance(cyc, dict) else "")
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


def read_fronts(bag_dir, topology: str | None = None) -> list[dict]:
    """The ParetoFront messages of a bag, in recording order (no ROS needed): dicts with run_id,
    topology, generation, final, objectives, evaluations, wall_time_s and ``designs`` (name ->
    array, one entry per front member)."""
    from bev_mdo.bag.reader import open_bag
    from bev_mdo.ros.pareto_publisher import PARETO_TOPIC

    fronts = []
    for _, m in open_bag(bag_dir).decoded([PARETO_TOPIC]):
        if topology is not None and m.topology != topology:
            continue
        n, names = int(m.designs.batch_size), list(m.designs.names)
        v = np.asarray(m.designs.values, float).reshape(len(names), n) if names else np.zeros((0, n))
        fronts.append({"run_id": m.run_id, "topology": m.topology, "generation": int(m.generation),
                       "final": bool(m.final), "objectives": list(m.objectives),
                       "designs": {k: v[j] for j, k in enumerate(names)},
                       "evaluations": int(m.evaluations), "wall_time_s": float(m.wall_time_s)})
    return fronts


def _run_one(cfg, evaluator, objectives, args, topology, on_front=None):
    from bev_mdo.mdo.driver import build_formulation
    from bev_mdo.mdo.pareto import run_nsga2

    form = build_formulation(cfg, evaluator, "mdf")
    res = run_nsga2(form, objectives, pop_size=args.pop, generations=args.generations, seed=args.seed,
                    on_generation=lambda g, n, s: print(f"  gen {g}: {n} evaluations, {s:.2f} s", file=sys.stderr),
                    on_front=on_front)
    x = {k: v for k, v in BENCHMARK[topology].items()}
    x["battery_kwh"] = 24.0
    row = np.array([[x[n] for n in form.problem.names]])
    r = form.analyse(row)
    b = {k: float(np.asarray(v)[0]) for k, v in r.values.items()}
    return res, b


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
        from bev_mdo.cli.optimize import with_run_key

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


def _write_front(path: Path, res) -> None:
    cols = list(res.names) + [o for o in res.objectives if o not in res.names]
    cols += sorted(k for k in res.values if k not in cols)
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(cols)
        for i in range(len(res.X)):
            w.writerow([f"{float(res.values[c][i]):.10g}" if c in res.values else "" for c in cols])


def _write_benchmark(path: Path, bench) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["topology", "kerb_kg", "thesis_kerb_kg", "accel_0_100_s", "thesis_accel_s", "cost_usd",
                    "thesis_cost_usd", "energy_kwh_100km", "thesis_energy_kwh_100km", "range_nedc_km",
                    "torque_margin_nm"])
        for t, b in bench.items():
            th = THESIS_4_5[t]
            w.writerow([t, f"{b['vehicle_mass_kg'] - 69.0:.2f}", th[0], f"{b['accel_time_0_100_s']:.2f}", th[1],
                        f"{b['powertrain_cost_usd']:.1f}", th[2], f"{b['energy_wh_per_km'] / 10:.2f}", th[3],
                        f"{b.get('range_nedc_km', float('nan')):.1f}", f"{b.get('drive_torque_margin_nm', float('nan')):.1f}"])


def _picks(results, bench):
    """Table 4-6: least energy with 0-100 no slower than the SM-SA benchmark; Table 4-7: least cost
    with energy no more than the SM-SA benchmark's."""
    ref = bench.get("SM-SA")
    out = {}
    for t, r in results.items():
        if not len(r.X) or ref is None:
            continue
        v = r.values
        e, a, c = v["energy_wh_per_km"], v["accel_time_0_100_s"], v["powertrain_cost_usd"]
        d = {}
        ok = a <= ref["accel_time_0_100_s"]
        if ok.any():
            i = int(np.flatnonzero(ok)[np.argmin(e[ok])])
            d["table_4_6"] = {**{n: float(v[n][i]) for n in r.names}, "energy_kwh_100km": float(e[i] / 10),
                              "change_pct": float(100 * (e[i] / ref["energy_wh_per_km"] - 1))}
        ok = e <= ref["energy_wh_per_km"]
        if ok.any():
            i = int(np.flatnonzero(ok)[np.argmin(c[ok])])
            d["table_4_7"] = {**{n: float(v[n][i]) for n in r.names}, "cost_usd": float(c[i]),
                              "change_pct": float(100 * (c[i] / ref["powertrain_cost_usd"] - 1))}
        out[t] = d
    return out


_FIGURE_NAMES = {("accel_time_0_100_s", "energy_wh_per_km"): "fig_4_5_energy_accel.png",
                 ("energy_wh_per_km", "powertrain_cost_usd"): "fig_4_6_energy_cost.png"}
_MARKS = {"SM-SA": "o", "DM-DA": "s", "IWM-SA": "^", "IWM-DA": "D"}


def _axis(name: str):
    """(scale factor, axis label) of an objective; energy in kWh/100 km as the thesis plots it."""
    from bev_mdo.mdo.units import label

    if name == "energy_wh_per_km":
        return 0.1, "energy consumption (kWh/100 km)"
    return 1.0, label(name)


def plot_pair(results, bench, xk: str, yk: str, path: Path, cycle: str = ""):
    """One Pareto projection: every topology's front and its 80 kW benchmark design (Table 4-4),
    same marker, black edge, larger. Returns the figure (closed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fx, xl = _axis(xk)
    fy, yl = _axis(yk)
    fig, ax = plt.subplots(figsize=(6.6, 4.8))
    for k, (t, r) in enumerate(results.items()):
        colour = f"C{k}"
        if len(r.X):
            ax.scatter(r.values[xk] * fx, r.values[yk] * fy, s=14, marker=_MARKS.get(t, "o"), color=colour,
                       label=f"{t} front")
        b = bench.get(t)
        if b and xk in b and yk in b:
            short = b.get("drive_torque_margin_nm", 0.0) < 0  # cannot deliver the cycle's torque
            ax.scatter([b[xk] * fx], [b[yk] * fy], s=110, marker=_MARKS.get(t, "o"),
                       facecolor="white" if short else colour, edgecolor=colour if short else "k", linewidth=2,
                       zorder=5, label=f"{t} benchmark (Table 4-4)" + (", torque margin < 0" if short else ""))
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(f"Pareto front projection{': ' + cycle if cycle else ''}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return fig


def _plots(out: Path, results, bench, objectives, cycle: str = "") -> list[Path]:
    """A projection for every pair of objectives (the thesis' Figs 4-5 and 4-6 keep their names);
    none for a single objective. Returns the written files."""
    written = []
    for i, xk in enumerate(objectives):
        for yk in objectives[i + 1:]:
            if (yk, xk) in _FIGURE_NAMES:
                xk_, yk_ = yk, xk
            else:
                xk_, yk_ = xk, yk
            name = _FIGURE_NAMES.get((xk_, yk_), f"pareto_{yk_}_vs_{xk_}.png")
            plot_pair(results, bench, xk_, yk_, out / name, cycle)
            written.append(out / name)
    return written


def torque_warnings(bench) -> list[str]:
    """One line per benchmark design whose drive-torque margin is negative (it cannot deliver the
    cycle's peak torque, so its energy and 0-100 time are not those of a feasible design)."""
    out = []
    for t, b in bench.items():
        m = b.get("drive_torque_margin_nm", float("nan"))
        if np.isfinite(m) and m < 0:
            out.append(f"warning: the {t} benchmark design (Table 4-4) has a negative drive-torque margin "
                       f"({m:.1f} N·m): it cannot deliver the cycle's peak torque; benchmark.csv lists it as "
                       "the thesis does, but it is not a feasible design here")
    return out
