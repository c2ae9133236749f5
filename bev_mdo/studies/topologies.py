"""The thesis' chapter-4 topology study (§4.4, Tables 4-4..4-7, Figs 4-5/4-6), without the CLI: a run
config for each topology, the Table 4-4 benchmark designs analysed, the Table 4-6 / 4-7 picks from the
fronts, the plots, and the ParetoFront messages of a bag read without ROS. ``bev-mdo pareto --topology T
| --all-topologies`` (bev_mdo/cli/pareto.py) runs NSGA-II per topology and calls these.
"""
from __future__ import annotations

import copy
import csv
from pathlib import Path

import numpy as np

from bev_mdo.disciplines import TOPOLOGY_DISCIPLINES
from bev_mdo.disciplines.common import UNITS
from bev_mdo.mdo.units import factor, label
from bev_mdo.models.topology import get_topology
from bev_mdo.figures import styled, subplots

# the study's objectives unless the config (problem.objectives) or --objectives names others
OBJECTIVES = ("energy_wh_per_km", "accel_time_0_100_s", "powertrain_cost_usd")
# design-variable bounds per topology (motor power per motor): for a variable of the topology that
# the config does not give (the rear motor of a two-axle topology studied from an SM-SA config)
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


def config_topology(raw) -> str:
    """The topology a raw config sets (``vehicle.topology``, else a discipline's ``topology``
    option; SM-SA if none). load_config rejects a config where they disagree."""
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
    variables: each with the config's own bounds where the config gives it, else the study's
    (``TOPOLOGY_BOUNDS``); a variable the topology does not have (``gear_ratio`` of IWM-*) is left out, and
    so is a ``problem.baseline`` that lacks one of the new topology's variables or gives one it does not have."""
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
        new = {k: dvs.get(k, {"lower": lo, "upper": hi, "initial": x0}) for k, (lo, hi, x0) in TOPOLOGY_BOUNDS[t].items()}
        new["battery_kwh"] = dvs.get("battery_kwh", {"lower": 18.0, "upper": 30.0, "initial": 24.0})
        cfg.setdefault("problem", {})["design_variables"] = new
        base = cfg["problem"].get("baseline")
        given = set((base.get("design") or {}) if isinstance(base, dict) else ())
        if isinstance(base, dict) and (set(new) - given or (set(dvs) - set(new)) & given):
            del cfg["problem"]["baseline"]  # a design of the config's own topology (IWM-*: with its gear_ratio)
    return cfg


def benchmark(form, topology: str) -> dict[str, float]:
    """Every MDA output at the topology's Table 4-4 benchmark design (24 kWh battery)."""
    x = {**BENCHMARK[topology], "battery_kwh": 24.0}
    r = form.analyse(np.array([[x[n] for n in form.problem.names]]))
    return {k: float(np.asarray(v)[0]) for k, v in r.values.items()}


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


def write_benchmark(path: Path, bench, configs) -> None:
    """benchmark.csv: each topology's Table 4-4 design (``bench``) under its run config (``configs``); the
    kerb mass is the vehicle mass less the config's load. Table 4-5's columns only when it describes the
    configs' vehicle (``thesis_vehicle``): another vehicle is not compared with the thesis' Leaf."""
    from bev_mdo.models.params import validate_vehicle

    thesis = all(thesis_vehicle(configs[t], t) for t in bench)
    cols = [("kerb_kg", "thesis_kerb_kg"), ("accel_0_100_s", "thesis_accel_s"), ("cost_usd", "thesis_cost_usd"),
            ("battery_energy_kwh_100km", "thesis_battery_energy_kwh_100km")]
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["topology", *[c for pair in cols for c in (pair if thesis else pair[:1])],
                    "range_nedc_km", "torque_margin_nm"])
        for t, b in bench.items():
            load_kg = validate_vehicle(configs[t].get("vehicle"))["load_kg"]
            ours = (f"{b['vehicle_mass_kg'] - load_kg:.2f}", f"{b['accel_time_0_100_s']:.2f}",
                    f"{b['powertrain_cost_usd']:.1f}", f"{b['energy_wh_per_km'] / 10:.2f}")
            w.writerow([t, *[c for pair in zip(ours, THESIS_4_5[t]) for c in (pair if thesis else pair[:1])],
                        f"{b.get('range_nedc_km', float('nan')):.1f}", f"{b.get('drive_torque_margin_nm', float('nan')):.1f}"])


def thesis_vehicle(config, topology: str) -> bool:
    """Whether Table 4-5 describes ``config``'s vehicle under ``topology``: its vehicle_mass, energy,
    acceleration and cost decide their answers as the thesis study's (config/topologies_artemis.yaml)
    do (binding.effective_config: vehicle parameters and choices, cycle, energy model, options)."""
    from bev_mdo.binding import effective_config
    from bev_mdo.config import RunConfig
    from bev_mdo.ros.paths import default_config
    from bev_mdo.yamlload import read_yaml_file

    try:
        thesis = RunConfig.load(config_for_topology(read_yaml_file(Path(default_config("topologies_artemis.yaml"))),
                                                    topology))
        return all(effective_config(config, n) == effective_config(thesis, n)
                   for n in ("vehicle_mass", "energy", "acceleration", "cost"))
    except (OSError, ValueError):  # no shipped thesis config, or a discipline the config does not have
        return False


PICKS_REFERENCE = "SM-SA benchmark design (Table 4-4)"  # every topology's picks are measured against it


def picks(results, bench):
    """Table 4-6: least energy with 0-100 no slower than the SM-SA benchmark; Table 4-7: least cost
    with energy no more than the SM-SA benchmark's. Every topology's ``change_pct`` is against the SM-SA
    benchmark (as the thesis' tables), named in ``reference`` with its value in the column's unit."""
    ref = bench.get("SM-SA")
    out = {}
    for t, r in results.items():
        if not len(r.X) or ref is None:
            continue
        v = r.values
        e, a, c = v["energy_wh_per_km"], v["accel_time_0_100_s"], v["powertrain_cost_usd"]
        d = {}
        # (table, the designs allowed, the quantity minimised, its column and divisor, its benchmark value)
        for key, ok, y, column, per, base in (
                ("table_4_6", a <= ref["accel_time_0_100_s"], e, "battery_energy_kwh_100km", 10, ref["energy_wh_per_km"]),
                ("table_4_7", e <= ref["energy_wh_per_km"], c, "cost_usd", 1, ref["powertrain_cost_usd"])):
            if ok.any():
                i = int(np.flatnonzero(ok)[np.argmin(y[ok])])
                d[key] = {**{n: float(v[n][i]) for n in r.names}, column: float(y[i] / per),
                          "change_pct": float(100 * (y[i] / base - 1)), "reference": PICKS_REFERENCE,
                          f"reference_{column}": float(base / per)}
        out[t] = d
    return out


_FIGURE_NAMES = {("accel_time_0_100_s", "energy_wh_per_km"): "fig_4_5_energy_accel.png",
                 ("energy_wh_per_km", "powertrain_cost_usd"): "fig_4_6_energy_cost.png"}
_MARKS = {"SM-SA": "o", "DM-DA": "s", "IWM-SA": "^", "IWM-DA": "D"}


def _axis(name: str):
    """(scale factor, axis label) of an objective, in the built-in disciplines' declared unit; energy in
    kWh/100 km as the thesis plots it."""
    if name == "energy_wh_per_km":
        return 100.0 * factor(UNITS[name], "kWh/km")[0], "battery energy (kWh/100 km)"
    return 1.0, label(name, UNITS)


@styled
def plot_pair(results, bench, xk: str, yk: str, path: Path, cycle: str = "", violated=()):
    """One Pareto projection: every topology's front and its 80 kW benchmark design (Table 4-4),
    same marker, black edge, larger; hollow where it is not a feasible design of the run (a topology in
    ``violated``, whose benchmark breaks a run constraint, or a negative torque margin). Returns the figure."""
    fx, xl = _axis(xk)
    fy, yl = _axis(yk)
    fig, ax = subplots(figsize=(6.6, 4.8))
    for k, (t, r) in enumerate(results.items()):
        colour = f"C{k}"
        if len(r.X):
            ax.scatter(r.values[xk] * fx, r.values[yk] * fy, s=14, marker=_MARKS.get(t, "o"), color=colour,
                       label=f"{t} front")
        b = bench.get(t)
        if b and xk in b and yk in b:
            short = b.get("drive_torque_margin_nm", 0.0) < 0  # cannot deliver the cycle's torque
            why = ", violates a constraint" if t in violated else ", torque margin < 0" if short else ""
            ax.scatter([b[xk] * fx], [b[yk] * fy], s=110, marker=_MARKS.get(t, "o"),
                       facecolor="white" if why else colour, edgecolor=colour if why else "k", linewidth=2,
                       zorder=5, label=f"{t} benchmark (Table 4-4){why}")
    ax.set_xlabel(xl)
    ax.set_ylabel(yl)
    ax.set_title(f"Pareto front projection{': ' + cycle if cycle else ''}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return fig


def plots(out: Path, results, bench, objectives, cycle: str = "", violated=()) -> list[Path]:
    """A projection for every pair of objectives (the thesis' Figs 4-5 and 4-6 keep their names);
    none for a single objective; ``violated``: as ``plot_pair``. Returns the written files."""
    written = []
    for i, xk in enumerate(objectives):
        for yk in objectives[i + 1:]:
            x, y = (yk, xk) if (yk, xk) in _FIGURE_NAMES else (xk, yk)  # the thesis' axes
            name = _FIGURE_NAMES.get((x, y), f"pareto_{y}_vs_{x}.png")
            plot_pair(results, bench, x, y, out / name, cycle, violated)
            written.append(out / name)
    return written


def violations(bench, configs) -> dict[str, list[dict]]:
    """Per topology, the run's constraints (the config's and the command line's ``--constraint``; not the
    monitored ones) that its benchmark design breaks, judged as NSGA-II judges a design (normalised
    constraint > 0): ``{"constraint": "accel_time_0_100_s <= 9", "output", "value", "limit", "unit"}``."""
    from bev_mdo.mdo.units import run_units

    out = {}
    for t, b in bench.items():
        prob = configs[t].problem
        rows = prob.constraint_rows
        if not rows:
            continue
        units = {k: u for k, u in run_units(configs[t].disciplines).items() if u != "1"}
        g = prob.g({n: np.array([b.get(n, np.nan)], float) for n, *_ in rows})[0]
        bad = [{"constraint": lab, "output": n, "value": float(b.get(n, np.nan)), "limit": float(bound),
                "unit": units.get(n, "")}
               for (n, _, bound, _), lab, gi in zip(rows, prob.constraint_labels, g) if gi > 0]
        if bad:
            out[t] = bad
    return out


def benchmark_warnings(bench, broken) -> list[str]:
    """One line per run constraint a benchmark design breaks (``broken``: ``violations``), and one for a
    negative drive-torque margin no constraint names (it cannot deliver the cycle's peak torque, so its
    energy and 0-100 time are not those of a feasible design)."""
    out = []
    for t, b in bench.items():
        named = set()
        for v in broken.get(t, []):
            named.add(v["output"])
            torque = " (it cannot deliver the cycle's peak torque)" if v["output"] == "drive_torque_margin_nm" else ""
            out.append(f"warning: the {t} benchmark design (Table 4-4) violates the run's constraint {v['constraint']}: "
                       f"its {v['output']} is {v['value']:.6g}{' ' + v['unit'] if v['unit'] else ''}{torque}; "
                       "benchmark.csv lists it and the figures draw it hollow, but it is not a feasible design of this run")
        m = b.get("drive_torque_margin_nm", float("nan"))
        if np.isfinite(m) and m < 0 and "drive_torque_margin_nm" not in named:
            out.append(f"warning: the {t} benchmark design (Table 4-4) has a negative drive-torque margin "
                       f"({m:.1f} N·m): it cannot deliver the cycle's peak torque; benchmark.csv lists it as "
                       "the thesis does, but it is not a feasible design here")
    return out


def ranking(results, objectives) -> dict[str, list[dict]]:
    """Per objective (``(name, maximised)``), the topologies ordered by their front's best value of it alone
    (each bought with the other objectives), ``{"topology", "best", "unit", "change_pct"}`` against the first.
    A topology without a feasible design is left out."""
    out = {}
    for name, maximised in objectives:
        rows = [(t, float((np.max if maximised else np.min)(r.values[name])))
                for t, r in results.items() if len(r.X) and name in r.values]
        rows.sort(key=lambda tv: -tv[1] if maximised else tv[1])
        if rows:
            first = rows[0][1]
            out[name] = [{"topology": t, "best": v, "unit": UNITS.get(name, ""),
                          "change_pct": float(100 * (v / first - 1)) if first else float("nan")} for t, v in rows]
    return out


def ranking_lines(ranked) -> list[str]:
    """``ranking`` as one line per objective: 'IWM-DA 115.17, DM-DA 118.88 (+3.2 %), ...'."""
    lines = []
    for name, rows in ranked.items():
        unit = f" ({rows[0]['unit']})" if rows[0]["unit"] not in ("", "1") else ""
        cells = [f"{r['topology']} {_plain(r['best'])}" + (f" ({r['change_pct']:+.1f} %)" if i else "")
                 for i, r in enumerate(rows)]
        lines.append(f"ranking by each front's best {name}{unit}: {', '.join(cells)}")
    return lines


def _plain(v: float) -> str:
    """A value as a table shows it, never in exponent form: 10055, 116.0, 2.448."""
    return f"{v:.0f}" if abs(v) >= 1000 else f"{v:.1f}" if abs(v) >= 100 else f"{v:.3f}"


def caveats(results, configs) -> list[str]:
    """What qualifies a ranking of this study's fronts, one line each: a 0-100 km/h time faster than the
    tyres' grip allows where the run's parameters switch the grip off (``acceleration.grip_force_n``:
    mu g on the driven axles, at the default mu and axle load share), motors rated above what the pack
    gives at its discharge limit where the run switches that limit off (``acceleration.battery_shaft_power_w``
    at the default efficiency), and the thesis' efficiency map (``motor_loss_model`` 0, the thesis set or
    none), which is not calibrated to measured cars (docs/validation.md)."""
    from bev_mdo.models import acceleration
    from bev_mdo.models.params import all_specs, validate_vehicle

    spec, out, fast = all_specs(), [], []
    mu = spec["tyre_grip_coefficient"].default
    vehicles = {t: validate_vehicle(configs[t].data.get("vehicle")) for t in results}  # once per topology
    for t, r in results.items():
        p = vehicles[t]
        if p["tyre_grip_coefficient"] > 0 or not len(r.X) or "accel_time_0_100_s" not in r.values:
            continue
        share = 1.0 if get_topology(t).two_axles else p["driven_axle_load_share"]
        floor = acceleration.V_END_M_S / (mu * p["gravity_m_s2"] * share)  # road load only adds to it
        best = float(np.min(r.values["accel_time_0_100_s"]))
        if best < floor:
            wheels = "every wheel" if share == 1 else f"{100 * share:.0f} % of the weight on the driven axle"
            fast.append(f"{t} {best:.2f} s (at least {floor:.2f} s with {wheels})")
    if fast:
        out.append(f"caveat: the parameters switch the tyres' grip limit off (tyre_grip_coefficient 0), and some "
                   f"fronts reach 0-100 km/h faster than grip mu {mu:g} allows: {'; '.join(fast)}")
    over = []  # with the battery limit off: front designs whose motors the pack cannot feed at the default limit
    eta = spec["battery_to_shaft_efficiency"].default
    for t, r in results.items():
        p, topo = vehicles[t], get_topology(t)
        col = {n: r.X[:, i] for i, n in enumerate(r.names)}
        if p["battery_to_shaft_efficiency"] > 0 or not len(r.X) or "motor_kw" not in col or "battery_kwh" not in col:
            continue
        motors_kw = topo.front_motors * col["motor_kw"] + topo.rear_motors * col.get("motor_rear_kw", 0.0)
        shaft_kw = acceleration.battery_shaft_power_w(col["battery_kwh"], {**p, "battery_to_shaft_efficiency": eta}) / 1e3
        bad = np.flatnonzero(motors_kw > shaft_kw)
        if len(bad):
            i = bad[np.argmax((motors_kw / shaft_kw)[bad])]
            over.append(f"{t} {len(bad)} of {len(r.X)} (the most over its pack: {motors_kw[i]:.0f} kW of motors on "
                        f"{col['battery_kwh'][i]:.1f} kWh, which gives {shaft_kw[i]:.0f} kW)")
    if over:
        out.append(f"caveat: the parameters switch the battery's limit on the 0-100 km/h time off "
                   f"(battery_to_shaft_efficiency 0); at {p['discharge_c_max']:g} C and shaft efficiency {eta:g}, these "
                   f"front designs have more motor than their pack gives: {'; '.join(over)}")
    thesis = [t for t in results if vehicles[t]["motor_loss_model"] == 0]
    if thesis:  # the study's energy is the topology model's: with the map (loss model 0) it is the thesis' own
        out.append(f"caveat: {', '.join(thesis)} ran on the thesis' efficiency map (motor_loss_model 0: the thesis set "
                   "or no set), not calibrated to measured cars: it over-predicts the energy differences between "
                   "variants of one car (docs/validation.md, pairs), so this energy ranking is the thesis model's, "
                   "not a measured car's")
    return out
